#pragma once
// A world's state as named arrays: what a checkpoint holds (World::saveState / World::restoreState; written
// to a trajectory by H5mdWriter::writeCheckpoint, one HDF5 dataset per array). Each array has one element
// type and a row width; the stores and caches that make up the state put their arrays under names of their
// own ("particles/position", "solver/keys", ...). Reading checks every array's type and shape, and keeps the
// first thing that does not fit as an error, so that a damaged or foreign checkpoint is refused with a
// message instead of being taken in part.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "volpar/engine/core/types.hpp"

namespace volpar {

class StateArchive {
 public:
  enum class Type : std::uint8_t { F64, F32, I64, U32, U8 };
  struct Array {
    std::string name;
    Type type = Type::F64;
    std::size_t width = 1;             ///< values per row (>= 1)
    std::vector<unsigned char> bytes;  ///< the values, row after row, native byte order
    [[nodiscard]] std::size_t values() const { return bytes.size() / typeSize(type); }
    [[nodiscard]] std::size_t rows() const { return values() / width; }
  };
  [[nodiscard]] static std::size_t typeSize(Type type);
  [[nodiscard]] static const char* typeName(Type type);

  void put(std::string name, std::span<const double> values, std::size_t width = 1);
  void put(std::string name, std::span<const float> values, std::size_t width = 1);
  void put(std::string name, std::span<const std::int64_t> values, std::size_t width = 1);
  void put(std::string name, std::span<const std::uint32_t> values, std::size_t width = 1);
  void put(std::string name, std::span<const std::uint8_t> values, std::size_t width = 1);
  /// [n, 3]
  void putVec3(std::string name, std::span<const Vec3> values);
  /// [n, 4] as (w, x, y, z)
  void putQuat(std::string name, std::span<const Quat> values);
  /// [n, 9], each matrix row by row
  void putMat3(std::string name, std::span<const Mat3> values);
  void putScalar(std::string name, double value) { put(std::move(name), std::span<const double>(&value, 1)); }
  void putScalar(std::string name, std::int64_t value) { put(std::move(name), std::span<const std::int64_t>(&value, 1)); }

  /// Adds an array as read from a file (replaces one of the same name).
  void add(Array array);
  [[nodiscard]] const Array* find(std::string_view name) const;
  [[nodiscard]] const std::vector<Array>& arrays() const { return arrays_; }
  /// The bytes of all arrays.
  [[nodiscard]] std::size_t bytes() const;

 private:
  void putBytes(std::string name, Type type, std::size_t width, const void* data, std::size_t count);
  std::vector<Array> arrays_;
};

/// Reads a StateArchive back, checking each array against what the reader expects. The first mismatch (or
/// fail() from the caller's own checks) is kept; reads after it return empty arrays and zeros.
class StateReader {
 public:
  explicit StateReader(const StateArchive& archive) : archive_(archive) {}

  /// The values of `name` (type T, `width` per row), with exactly `rows` rows where given.
  template <class T>
  std::vector<T> get(std::string_view name, std::size_t width = 1, std::optional<std::size_t> rows = std::nullopt);
  std::vector<Vec3> vec3(std::string_view name, std::optional<std::size_t> rows = std::nullopt);
  std::vector<Quat> quat(std::string_view name, std::optional<std::size_t> rows = std::nullopt);
  std::vector<Mat3> mat3(std::string_view name, std::optional<std::size_t> rows = std::nullopt);
  double f64(std::string_view name);
  std::int64_t i64(std::string_view name);
  /// Whether the checkpoint has an array of this name (for arrays that older checkpoints lack).
  [[nodiscard]] bool has(std::string_view name) const { return archive_.find(name) != nullptr; }

  /// Records a failure of the caller's own (the first one counts).
  void fail(std::string message) {
    if (error_.empty()) error_ = std::move(message);
  }
  /// Fails unless every index is below `bound` (`what` names them in the message).
  void checkIndices(std::span<const std::uint32_t> indices, std::size_t bound, std::string_view what);
  [[nodiscard]] bool ok() const { return error_.empty(); }
  [[nodiscard]] const std::string& error() const { return error_; }

 private:
  const StateArchive::Array* expect(std::string_view name, StateArchive::Type type, std::size_t width,
                                    std::optional<std::size_t> rows);
  const StateArchive& archive_;
  std::string error_;
};

}  // namespace volpar
