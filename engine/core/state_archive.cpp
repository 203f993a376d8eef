#include "volpar/engine/core/state_archive.hpp"

#include <algorithm>
#include <cstring>

namespace volpar {

namespace {

template <class T>
constexpr StateArchive::Type typeOf();
template <>
constexpr StateArchive::Type typeOf<double>() { return StateArchive::Type::F64; }
template <>
constexpr StateArchive::Type typeOf<float>() { return StateArchive::Type::F32; }
template <>
constexpr StateArchive::Type typeOf<std::int64_t>() { return StateArchive::Type::I64; }
template <>
constexpr StateArchive::Type typeOf<std::uint32_t>() { return StateArchive::Type::U32; }
template <>
constexpr StateArchive::Type typeOf<std::uint8_t>() { return StateArchive::Type::U8; }

}  // namespace

std::size_t StateArchive::typeSize(Type type) {
  switch (type) {
    case Type::F64: return 8;
    case Type::F32: return 4;
    case Type::I64: return 8;
    case Type::U32: return 4;
    case Type::U8: return 1;
  }
  return 1;
}

const char* StateArchive::typeName(Type type) {
  switch (type) {
    case Type::F64: return "64-bit floating point";
    case Type::F32: return "32-bit floating point";
    case Type::I64: return "64-bit signed integer";
    case Type::U32: return "32-bit unsigned integer";
    case Type::U8: return "8-bit unsigned integer";
  }
  return "?";
}

void StateArchive::putBytes(std::string name, Type type, std::size_t width, const void* data, std::size_t count) {
  Array a;
  a.name = std::move(name);
  a.type = type;
  a.width = std::max<std::size_t>(width, 1);
  a.bytes.resize(count * typeSize(type));
  if (count > 0) std::memcpy(a.bytes.data(), data, a.bytes.size());
  add(std::move(a));
}

void StateArchive::put(std::string name, std::span<const double> v, std::size_t width) {
  putBytes(std::move(name), Type::F64, width, v.data(), v.size());
}
void StateArchive::put(std::string name, std::span<const float> v, std::size_t width) {
  putBytes(std::move(name), Type::F32, width, v.data(), v.size());
}
void StateArchive::put(std::string name, std::span<const std::int64_t> v, std::size_t width) {
  putBytes(std::move(name), Type::I64, width, v.data(), v.size());
}
void StateArchive::put(std::string name, std::span<const std::uint32_t> v, std::size_t width) {
  putBytes(std::move(name), Type::U32, width, v.data(), v.size());
}
void StateArchive::put(std::string name, std::span<const std::uint8_t> v, std::size_t width) {
  putBytes(std::move(name), Type::U8, width, v.data(), v.size());
}

void StateArchive::putVec3(std::string name, std::span<const Vec3> values) {
  std::vector<double> flat;
  flat.reserve(3 * values.size());
  for (const Vec3& v : values) flat.insert(flat.end(), {v.x(), v.y(), v.z()});
  put(std::move(name), std::span<const double>(flat), 3);
}

void StateArchive::putQuat(std::string name, std::span<const Quat> values) {
  std::vector<double> flat;
  flat.reserve(4 * values.size());
  for (const Quat& q : values) flat.insert(flat.end(), {q.w(), q.x(), q.y(), q.z()});
  put(std::move(name), std::span<const double>(flat), 4);
}

void StateArchive::putMat3(std::string name, std::span<const Mat3> values) {
  std::vector<double> flat;
  flat.reserve(9 * values.size());
  for (const Mat3& m : values)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) flat.push_back(m(r, c));
  put(std::move(name), std::span<const double>(flat), 9);
}

void StateArchive::add(Array array) {
  for (Array& a : arrays_)
    if (a.name == array.name) {
      a = std::move(array);
      return;
    }
  arrays_.push_back(std::move(array));
}

const StateArchive::Array* StateArchive::find(std::string_view name) const {
  for (const Array& a : arrays_)
    if (a.name == name) return &a;
  return nullptr;
}

std::size_t StateArchive::bytes() const {
  std::size_t n = 0;
  for (const Array& a : arrays_) n += a.bytes.size();
  return n;
}

const StateArchive::Array* StateReader::expect(std::string_view name, StateArchive::Type type, std::size_t width,
                                               std::optional<std::size_t> rows) {
  if (!ok()) return nullptr;
  const StateArchive::Array* a = archive_.find(name);
  const std::string n(name);
  if (!a) {
    fail("the checkpoint has no '" + n + "'");
    return nullptr;
  }
  if (a->type != type) {
    fail("checkpoint array '" + n + "' holds " + StateArchive::typeName(a->type) + " values; expected " +
         StateArchive::typeName(type));
    return nullptr;
  }
  if (a->width != width || a->values() % width != 0 || a->bytes.size() % StateArchive::typeSize(type) != 0) {
    fail("checkpoint array '" + n + "' has rows of " + std::to_string(a->width) + " values; expected " + std::to_string(width));
    return nullptr;
  }
  if (rows && a->rows() != *rows) {
    fail("checkpoint array '" + n + "' has " + std::to_string(a->rows()) + " rows; expected " + std::to_string(*rows));
    return nullptr;
  }
  return a;
}

template <class T>
std::vector<T> StateReader::get(std::string_view name, std::size_t width, std::optional<std::size_t> rows) {
  std::vector<T> out;
  const StateArchive::Array* a = expect(name, typeOf<T>(), width, rows);
  if (!a) return out;
  out.resize(a->values());
  if (!out.empty()) std::memcpy(out.data(), a->bytes.data(), a->bytes.size());
  return out;
}

template std::vector<double> StateReader::get<double>(std::string_view, std::size_t, std::optional<std::size_t>);
template std::vector<float> StateReader::get<float>(std::string_view, std::size_t, std::optional<std::size_t>);
template std::vector<std::int64_t> StateReader::get<std::int64_t>(std::string_view, std::size_t, std::optional<std::size_t>);
template std::vector<std::uint32_t> StateReader::get<std::uint32_t>(std::string_view, std::size_t, std::optional<std::size_t>);
template std::vector<std::uint8_t> StateReader::get<std::uint8_t>(std::string_view, std::size_t, std::optional<std::size_t>);

std::vector<Vec3> StateReader::vec3(std::string_view name, std::optional<std::size_t> rows) {
  const std::vector<double> flat = get<double>(name, 3, rows);
  std::vector<Vec3> out(flat.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
  return out;
}

std::vector<Quat> StateReader::quat(std::string_view name, std::optional<std::size_t> rows) {
  const std::vector<double> flat = get<double>(name, 4, rows);
  std::vector<Quat> out(flat.size() / 4);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Quat(flat[4 * i], flat[4 * i + 1], flat[4 * i + 2], flat[4 * i + 3]);
  return out;
}

std::vector<Mat3> StateReader::mat3(std::string_view name, std::optional<std::size_t> rows) {
  const std::vector<double> flat = get<double>(name, 9, rows);
  std::vector<Mat3> out(flat.size() / 9);
  for (std::size_t i = 0; i < out.size(); ++i)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) out[i](r, c) = flat[9 * i + static_cast<std::size_t>(3 * r + c)];
  return out;
}

double StateReader::f64(std::string_view name) {
  const std::vector<double> v = get<double>(name, 1, 1);
  return v.empty() ? 0.0 : v[0];
}

std::int64_t StateReader::i64(std::string_view name) {
  const std::vector<std::int64_t> v = get<std::int64_t>(name, 1, 1);
  return v.empty() ? 0 : v[0];
}

void StateReader::checkIndices(std::span<const std::uint32_t> indices, std::size_t bound, std::string_view what) {
  for (const std::uint32_t i : indices)
    if (i >= bound) {
      fail("the checkpoint's " + std::string(what) + " refer to index " + std::to_string(i) + " of " +
           std::to_string(bound));
      return;
    }
}

}  // namespace volpar
