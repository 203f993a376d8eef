#include "engine/io/h5md_reader.hpp"

#include <hdf5.h>

namespace volpar {

namespace {

struct ReadFailure {
  std::string what;
};

class Handle {
 public:
  Handle(hid_t id, herr_t (*close)(hid_t), const std::string& what) : id_(id), close_(close) {
    if (id < 0) throw ReadFailure{what};
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() {
    if (id_ >= 0) close_(id_);
  }
  [[nodiscard]] hid_t get() const { return id_; }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

std::vector<hsize_t> dims(hid_t ds) {
  Handle space(H5Dget_space(ds), H5Sclose, "dataspace");
  const int rank = H5Sget_simple_extent_ndims(space.get());
  std::vector<hsize_t> d(static_cast<std::size_t>(std::max(rank, 0)));
  if (rank > 0) H5Sget_simple_extent_dims(space.get(), d.data(), nullptr);
  return d;
}

template <class T>
std::vector<T> readAll(hid_t file, const std::string& name, hid_t memType) {
  Handle ds(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose, "missing dataset " + name);
  hsize_t n = 1;
  for (const hsize_t d : dims(ds.get())) n *= d;
  std::vector<T> out(n);
  if (n > 0 && H5Dread(ds.get(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
    throw ReadFailure{"cannot read " + name};
  return out;
}

/// Row `row` of a [T, N, k] dataset as N*k doubles.
std::vector<double> readRow(hid_t file, const std::string& name, std::size_t row) {
  Handle ds(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose, "missing dataset " + name);
  std::vector<hsize_t> d = dims(ds.get());
  if (d.empty() || row >= d[0]) throw ReadFailure{"frame " + std::to_string(row) + " out of range in " + name};
  std::vector<hsize_t> start(d.size(), 0), count = d;
  start[0] = row;
  count[0] = 1;
  Handle fileSpace(H5Dget_space(ds.get()), H5Sclose, "dataspace");
  H5Sselect_hyperslab(fileSpace.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
  Handle memSpace(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr), H5Sclose, "dataspace");
  hsize_t n = 1;
  for (const hsize_t c : count) n *= c;
  std::vector<double> out(n);
  if (n > 0 && H5Dread(ds.get(), H5T_NATIVE_DOUBLE, memSpace.get(), fileSpace.get(), H5P_DEFAULT, out.data()) < 0)
    throw ReadFailure{"cannot read " + name};
  return out;
}

std::string readStringAttr(hid_t file, const std::string& object, const std::string& name) {
  Handle attr(H5Aopen_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
              "missing attribute " + object + "@" + name);
  Handle type(H5Aget_type(attr.get()), H5Tclose, "attribute type");
  if (H5Tis_variable_str(type.get()) > 0) {
    char* s = nullptr;
    Handle mem(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
    H5Tset_size(mem.get(), H5T_VARIABLE);
    H5Tset_cset(mem.get(), H5Tget_cset(type.get()));
    if (H5Aread(attr.get(), mem.get(), &s) < 0) throw ReadFailure{"cannot read " + name};
    std::string out = s ? s : "";
    H5free_memory(s);
    return out;
  }
  const std::size_t size = H5Tget_size(type.get());
  std::string out(size, '\0');
  if (H5Aread(attr.get(), type.get(), out.data()) < 0) throw ReadFailure{"cannot read " + name};
  out.erase(out.find_last_not_of('\0') + 1);
  return out;
}

std::vector<std::string> readStrings(hid_t file, const std::string& name, bool scalar) {
  Handle ds(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose, "missing dataset " + name);
  const std::size_t n = scalar ? 1 : static_cast<std::size_t>(dims(ds.get()).at(0));
  std::vector<char*> ptrs(n, nullptr);
  Handle mem(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
  H5Tset_size(mem.get(), H5T_VARIABLE);
  H5Tset_cset(mem.get(), H5T_CSET_UTF8);
  if (n > 0 && H5Dread(ds.get(), mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) < 0)
    throw ReadFailure{"cannot read " + name};
  std::vector<std::string> out;
  for (char* p : ptrs) {
    out.emplace_back(p ? p : "");
    H5free_memory(p);
  }
  return out;
}

}  // namespace

struct H5mdReader::Impl {
  hid_t file = H5I_INVALID_HID;
  std::string path;
};

H5mdReader::H5mdReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

H5mdReader::~H5mdReader() {
  if (impl_ && impl_->file >= 0) H5Fclose(impl_->file);
}

Result<std::unique_ptr<H5mdReader>> H5mdReader::open(const std::string& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  if (H5Fis_hdf5(path.c_str()) <= 0) return Error{path, 0, 0, "not an HDF5 file (or cannot be opened)"};
  impl->file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (impl->file < 0) return Error{path, 0, 0, "cannot open HDF5 file"};
  if (H5Lexists(impl->file, "h5md", H5P_DEFAULT) <= 0) {
    H5Fclose(impl->file);
    return Error{path, 0, 0, "not an H5MD file (no /h5md group)"};
  }
  return std::unique_ptr<H5mdReader>(new H5mdReader(std::move(impl)));
}

Result<TrajectorySummary> H5mdReader::summary() const {
  const hid_t f = impl_->file;
  TrajectorySummary s;
  try {
    s.creatorName = readStringAttr(f, "h5md/creator", "name");
    s.creatorVersion = readStringAttr(f, "h5md/creator", "version");
    s.sceneName = readStringAttr(f, "parameters", "scene_name");
    s.sceneText = readStrings(f, "parameters/scene", true).at(0);
    s.step = readAll<std::int64_t>(f, "particles/all/position/step", H5T_NATIVE_INT64);
    s.time = readAll<double>(f, "particles/all/position/time", H5T_NATIVE_DOUBLE);
    s.frames = s.step.size();
    s.particles = readAll<double>(f, "particles/all/radius", H5T_NATIVE_DOUBLE).size();
    s.bodyNames = readStrings(f, "particles/bodies/name", false);
    s.bodies = s.bodyNames.size();
    s.kinetic = readAll<double>(f, "observables/kinetic_energy/value", H5T_NATIVE_DOUBLE);
    s.potential = readAll<double>(f, "observables/potential_energy/value", H5T_NATIVE_DOUBLE);
    s.total = readAll<double>(f, "observables/total_energy/value", H5T_NATIVE_DOUBLE);
    if (H5Lexists(f, "patches", H5P_DEFAULT) > 0) {
      s.patchOffset = readAll<std::int64_t>(f, "patches/offset", H5T_NATIVE_INT64);
      s.patchCount = readAll<std::int64_t>(f, "patches/count", H5T_NATIVE_INT64);
    }
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
  return s;
}

namespace {

Result<std::vector<Vec3>> vec3Row(hid_t file, const std::string& path, const std::string& name, std::size_t frame) {
  try {
    const std::vector<double> raw = readRow(file, name, frame);
    std::vector<Vec3> out(raw.size() / 3);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]);
    return out;
  } catch (const ReadFailure& e) {
    return Error{path, 0, 0, e.what};
  }
}

}  // namespace

Result<std::vector<Vec3>> H5mdReader::positions(std::size_t frame) const {
  return vec3Row(impl_->file, impl_->path, "particles/all/position/value", frame);
}

Result<std::vector<Vec3>> H5mdReader::bodyPositions(std::size_t frame) const {
  return vec3Row(impl_->file, impl_->path, "particles/bodies/position/value", frame);
}

Result<std::vector<Quat>> H5mdReader::bodyOrientations(std::size_t frame) const {
  try {
    const std::vector<double> raw = readRow(impl_->file, "particles/bodies/orientation/value", frame);
    std::vector<Quat> out(raw.size() / 4);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = Quat(raw[4 * i], raw[4 * i + 1], raw[4 * i + 2], raw[4 * i + 3]);
    return out;
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
}

}  // namespace volpar
