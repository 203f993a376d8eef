#include "volpar/engine/io/h5md_reader.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>

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
  Handle(Handle&& o) noexcept : id_(o.id_), close_(o.close_) { o.id_ = H5I_INVALID_HID; }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle& operator=(Handle&&) = delete;
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
  if (rank < 0 || rank > 8) throw ReadFailure{"unreadable dataspace"};
  std::vector<hsize_t> d(static_cast<std::size_t>(rank));
  if (rank > 0 && H5Sget_simple_extent_dims(space.get(), d.data(), nullptr) < 0) throw ReadFailure{"unreadable dataspace"};
  return d;
}

std::string shapeText(const std::vector<hsize_t>& d) {
  std::string out = "[";
  for (std::size_t i = 0; i < d.size(); ++i) out += (i ? ", " : "") + std::to_string(d[i]);
  return out + "]";
}

/// What a dataset must be before it is read: its class, rank and the sizes of its trailing dimensions.
struct Expect {
  H5T_class_t typeClass;  // H5T_INTEGER or H5T_FLOAT (either is read as numbers), H5T_STRING
  int rank;                       // kOneValue: a scalar, or an array of one element
  std::vector<hsize_t> trailing;  // sizes of the last dimensions (e.g. {3} for [T, N, 3])
  const char* what;               // for messages: "one integer per frame", ...
};
constexpr int kOneValue = -1;

/// Dataset `name`, open, after checking it against `e`: numbers where numbers are expected, strings where
/// strings, the rank and trailing sizes, and a total size the file can hold (`limit` bytes); its shape into `d`.
Handle openChecked(hid_t file, const std::string& name, const Expect& e, std::uint64_t limit, std::vector<hsize_t>& d) {
  if (H5Lexists(file, name.c_str(), H5P_DEFAULT) <= 0) throw ReadFailure{"missing dataset /" + name + " (" + e.what + ")"};
  {
    Handle object(H5Oopen(file, name.c_str(), H5P_DEFAULT), H5Oclose, "cannot open /" + name);
    if (H5Iget_type(object.get()) != H5I_DATASET) throw ReadFailure{"/" + name + " is not a dataset; expected " + e.what};
  }
  Handle ds(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose, "cannot open dataset /" + name);
  Handle type(H5Dget_type(ds.get()), H5Tclose, "datatype of /" + name);
  const H5T_class_t c = H5Tget_class(type.get());
  const bool numeric = c == H5T_INTEGER || c == H5T_FLOAT;
  if (e.typeClass == H5T_STRING ? c != H5T_STRING : !numeric)
    throw ReadFailure{"/" + name + " holds " + (c == H5T_STRING ? "strings" : c == H5T_COMPOUND ? "compound records" : "values of another type") +
                      "; expected " + e.what};
  d = dims(ds.get());
  const bool rankOk = e.rank == kOneValue ? d.empty() || (d.size() == 1 && d[0] == 1) : static_cast<int>(d.size()) == e.rank;
  if (!rankOk) throw ReadFailure{"/" + name + " has shape " + shapeText(d) + "; expected " + e.what};
  for (std::size_t k = 0; k < e.trailing.size(); ++k)
    if (d[d.size() - e.trailing.size() + k] != e.trailing[k])
      throw ReadFailure{"/" + name + " has shape " + shapeText(d) + "; expected " + e.what};
  // the elements it claims must fit in what the file can hold (compression gives at most about 1000 : 1)
  long double bytes = 8.0L;
  for (const hsize_t k : d) bytes *= static_cast<long double>(k);
  if (bytes > static_cast<long double>(limit))
    throw ReadFailure{"/" + name + " claims shape " + shapeText(d) + ", more than the file can hold; expected " + e.what};
  return ds;
}

std::size_t elements(const std::vector<hsize_t>& d) {
  hsize_t n = 1;
  for (const hsize_t k : d) n *= k;
  return static_cast<std::size_t>(n);
}

template <class T>
std::vector<T> readAll(hid_t file, const std::string& name, hid_t memType, const Expect& e, std::uint64_t limit) {
  std::vector<hsize_t> d;
  const Handle ds = openChecked(file, name, e, limit, d);
  std::vector<T> out(elements(d));
  if (!out.empty() && H5Dread(ds.get(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
    throw ReadFailure{"cannot read /" + name + " as " + e.what};
  return out;
}

/// Row `row` of a [T, N, k] dataset as N*k doubles.
std::vector<double> readRow(hid_t file, const std::string& name, std::size_t row, const Expect& e, std::uint64_t limit) {
  std::vector<hsize_t> d;
  const Handle ds = openChecked(file, name, e, limit, d);
  if (row >= d[0]) throw ReadFailure{"frame " + std::to_string(row) + " out of range in /" + name + " (" + std::to_string(d[0]) + " frames)"};
  std::vector<hsize_t> start(d.size(), 0), count = d;
  start[0] = row;
  count[0] = 1;
  Handle fileSpace(H5Dget_space(ds.get()), H5Sclose, "dataspace");
  if (H5Sselect_hyperslab(fileSpace.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr) < 0)
    throw ReadFailure{"cannot select frame " + std::to_string(row) + " of /" + name};
  Handle memSpace(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr), H5Sclose, "dataspace");
  std::vector<double> out(elements(count));
  if (!out.empty() && H5Dread(ds.get(), H5T_NATIVE_DOUBLE, memSpace.get(), fileSpace.get(), H5P_DEFAULT, out.data()) < 0)
    throw ReadFailure{"cannot read /" + name};
  return out;
}

/// A string attribute: one string (a scalar, or an array of one), fixed or variable length.
std::string readStringAttr(hid_t file, const std::string& object, const std::string& name, std::uint64_t limit) {
  const std::string where = "/" + object + "@" + name;
  if (H5Lexists(file, object.c_str(), H5P_DEFAULT) <= 0 || H5Aexists_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT) <= 0)
    throw ReadFailure{"missing attribute " + where + " (a string)"};
  Handle attr(H5Aopen_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
              "cannot open attribute " + where);
  Handle type(H5Aget_type(attr.get()), H5Tclose, "attribute type");
  if (H5Tget_class(type.get()) != H5T_STRING) throw ReadFailure{where + " is not a string; expected a string"};
  Handle space(H5Aget_space(attr.get()), H5Sclose, "attribute dataspace");
  const hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (count != 1) throw ReadFailure{where + " holds " + std::to_string(count) + " strings; expected one"};
  if (H5Tis_variable_str(type.get()) > 0) {
    char* s = nullptr;
    Handle mem(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
    H5Tset_size(mem.get(), H5T_VARIABLE);
    H5Tset_cset(mem.get(), H5Tget_cset(type.get()));
    if (H5Aread(attr.get(), mem.get(), &s) < 0) throw ReadFailure{"cannot read " + where};
    std::string out = s ? s : "";
    H5free_memory(s);
    return out;
  }
  const std::size_t size = H5Tget_size(type.get());
  if (size == 0 || size > limit) throw ReadFailure{where + " is a string of " + std::to_string(size) + " bytes; expected a short string"};
  std::string out(size, '\0');
  if (H5Aread(attr.get(), type.get(), out.data()) < 0) throw ReadFailure{"cannot read " + where};
  out.erase(out.find_last_not_of('\0') + 1);
  return out;
}

/// A string dataset: `scalar`, one string (a scalar or an array of one); else a list of them.
std::vector<std::string> readStrings(hid_t file, const std::string& name, bool scalar, std::uint64_t limit) {
  const Expect e{H5T_STRING, scalar ? kOneValue : 1, {}, scalar ? "one string" : "a list of strings"};
  std::vector<hsize_t> d;
  const Handle ds = openChecked(file, name, e, limit, d);
  const std::size_t n = d.empty() ? 1 : static_cast<std::size_t>(d[0]);
  Handle type(H5Dget_type(ds.get()), H5Tclose, "datatype of /" + name);
  std::vector<std::string> out;
  if (H5Tis_variable_str(type.get()) > 0) {
    std::vector<char*> ptrs(n, nullptr);
    Handle mem(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
    H5Tset_size(mem.get(), H5T_VARIABLE);
    H5Tset_cset(mem.get(), H5T_CSET_UTF8);
    if (n > 0 && H5Dread(ds.get(), mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) < 0)
      throw ReadFailure{"cannot read /" + name + " as " + e.what};
    for (char* p : ptrs) {
      out.emplace_back(p ? p : "");
      H5free_memory(p);
    }
    return out;
  }
  // fixed-length strings
  const std::size_t size = H5Tget_size(type.get());
  if (size == 0 || static_cast<long double>(size) * static_cast<long double>(n) > static_cast<long double>(limit))
    throw ReadFailure{"/" + name + " holds strings larger than the file; expected " + e.what};
  std::string raw(size * n, '\0');
  if (n > 0 && H5Dread(ds.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, raw.data()) < 0)
    throw ReadFailure{"cannot read /" + name + " as " + e.what};
  for (std::size_t i = 0; i < n; ++i) {
    std::string one = raw.substr(i * size, size);
    one.erase(one.find_last_not_of('\0') + 1);
    out.push_back(std::move(one));
  }
  return out;
}

/// An optional attribute holding one value (a scalar, or an array of one) of class H5T_INTEGER, or with
/// `floatToo` also H5T_FLOAT, read as `memType` into `out`; false when the object or the attribute is absent.
/// `notOne`: the message's end where it holds anything else.
bool readOneValueAttr(hid_t file, const std::string& object, const std::string& name, bool floatToo, hid_t memType,
                      void* out, const char* notOne) {
  const std::string where = "/" + object + "@" + name;
  if (H5Lexists(file, object.c_str(), H5P_DEFAULT) <= 0 || H5Aexists_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT) <= 0)
    return false;
  Handle attr(H5Aopen_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
              "cannot open attribute " + where);
  Handle type(H5Aget_type(attr.get()), H5Tclose, "attribute type");
  Handle space(H5Aget_space(attr.get()), H5Sclose, "attribute dataspace");
  const H5T_class_t c = H5Tget_class(type.get());
  if ((c != H5T_INTEGER && !(floatToo && c == H5T_FLOAT)) || H5Sget_simple_extent_npoints(space.get()) != 1)
    throw ReadFailure{where + notOne};
  if (H5Aread(attr.get(), memType, out) < 0) throw ReadFailure{"cannot read " + where};
  return true;
}

/// An optional whole-number attribute (a scalar); nullopt when the object or the attribute is absent.
std::optional<std::int64_t> readCountAttr(hid_t file, const std::string& object, const std::string& name) {
  std::int64_t v = 0;
  if (!readOneValueAttr(file, object, name, false, H5T_NATIVE_INT64, &v, " is not one whole number; expected the count of complete frames"))
    return std::nullopt;
  return v;
}

/// An optional number attribute (one finite value); nullopt when the object or the attribute is absent.
std::optional<double> readNumberAttr(hid_t file, const std::string& object, const std::string& name) {
  double v = 0.0;
  if (!readOneValueAttr(file, object, name, true, H5T_NATIVE_DOUBLE, &v, " is not one number")) return std::nullopt;
  if (!std::isfinite(v)) throw ReadFailure{"/" + object + "@" + name + " is not a finite number"};
  return v;
}

}  // namespace

struct H5mdReader::Impl {
  hid_t file = H5I_INVALID_HID;
  std::string path;
  std::uint64_t limit = 0;  ///< the most bytes a dataset of this file can hold (compression included)
  std::uint64_t fileSize = 0;
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
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return Error{path, 0, 0, "cannot read the file's size: " + ec.message()};
  // deflate packs at most about 1032 : 1; room for that and for small files
  impl->limit = static_cast<std::uint64_t>(size) * 1100u + (std::uint64_t{1} << 20);
  impl->fileSize = static_cast<std::uint64_t>(size);
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
  const std::uint64_t limit = impl_->limit;
  TrajectorySummary s;
  const Expect perFrame{H5T_FLOAT, 1, {}, "one number per frame, [T]"};
  const Expect stepPerFrame{H5T_INTEGER, 1, {}, "one step number per frame, [T]"};
  try {
    s.creatorName = readStringAttr(f, "h5md/creator", "name", limit);
    s.creatorVersion = readStringAttr(f, "h5md/creator", "version", limit);
    s.sceneName = readStringAttr(f, "parameters", "scene_name", limit);
    s.sceneText = readStrings(f, "parameters/scene", true, limit).at(0);
    s.step = readAll<std::int64_t>(f, "particles/all/position/step", H5T_NATIVE_INT64, stepPerFrame, limit);
    s.time = readAll<double>(f, "particles/all/position/time", H5T_NATIVE_DOUBLE, perFrame, limit);
    s.frames = s.step.size();
    // a run killed (or stopped by a full disk) between commits: frames_complete excludes the frames written since
    // the last commit, whole or cut short
    const std::optional<std::int64_t> complete = readCountAttr(f, "parameters", "frames_complete");
    if (complete) {
      if (*complete < 0 || static_cast<std::uint64_t>(*complete) > s.frames)
        throw ReadFailure{"/parameters@frames_complete is " + std::to_string(*complete) + " but /particles/all/position/step has " +
                          std::to_string(s.frames) + " entries; expected the count of them or fewer (frames written after the last commit)"};
      s.tornFrames = s.frames - static_cast<std::size_t>(*complete);
      s.frames = static_cast<std::size_t>(*complete);
    }
    s.particles = readAll<double>(f, "particles/all/radius", H5T_NATIVE_DOUBLE, {H5T_FLOAT, 1, {}, "one radius per particle, [P]"}, limit).size();
    s.bodyNames = readStrings(f, "particles/bodies/name", false, limit);
    s.bodies = s.bodyNames.size();
    s.kinetic = readAll<double>(f, "observables/kinetic_energy/value", H5T_NATIVE_DOUBLE, perFrame, limit);
    s.potential = readAll<double>(f, "observables/potential_energy/value", H5T_NATIVE_DOUBLE, perFrame, limit);
    s.total = readAll<double>(f, "observables/total_energy/value", H5T_NATIVE_DOUBLE, perFrame, limit);
    s.checkpointStep = std::max<std::int64_t>(readCountAttr(f, "checkpoint", "step").value_or(-1), -1);
    if (H5Lexists(f, "patches", H5P_DEFAULT) > 0) {
      const Expect rows{H5T_INTEGER, 1, {}, "one row number per frame, [T]"};
      s.patchOffset = readAll<std::int64_t>(f, "patches/offset", H5T_NATIVE_INT64, rows, limit);
      s.patchCount = readAll<std::int64_t>(f, "patches/count", H5T_NATIVE_INT64, rows, limit);
    }
    // the per-frame records agree with each other and with the frames of the positions (each record of a
    // frame cut short may be there or not, whichever of them the run had extended when it stopped)
    const std::size_t written = complete ? std::numeric_limits<std::size_t>::max() : s.frames;
    const std::string expected = complete ? std::to_string(s.frames) + " complete frames (or more, written after the last commit)"
                                          : std::to_string(s.frames) + " frames";
    const auto frames = [&](const std::string& name, std::size_t n) {
      if (n < s.frames || n > written)
        throw ReadFailure{"/" + name + " has " + std::to_string(n) + " entries; expected one per frame, " + expected};
    };
    frames("particles/all/position/time", s.time.size());
    frames("observables/kinetic_energy/value", s.kinetic.size());
    frames("observables/potential_energy/value", s.potential.size());
    frames("observables/total_energy/value", s.total.size());
    if (!s.patchOffset.empty() || !s.patchCount.empty()) {
      frames("patches/offset", s.patchOffset.size());
      frames("patches/count", s.patchCount.size());
      for (std::size_t i = 0; i < s.frames; ++i)
        if (s.patchOffset[i] < 0 || s.patchCount[i] < 0 ||
            (i > 0 && s.patchOffset[i] != s.patchOffset[i - 1] + s.patchCount[i - 1]))
          throw ReadFailure{"/patches/offset and /patches/count disagree at frame " + std::to_string(i) +
                            "; expected consecutive row ranges"};
    }
    const Expect positions{H5T_FLOAT, 3, {static_cast<hsize_t>(s.particles), 3}, "positions [T, P, 3]"};
    std::vector<hsize_t> d;
    openChecked(f, "particles/all/position/value", positions, limit, d);  // (its shape is all it needs)
    if (d[0] < s.frames || d[0] > written)
      throw ReadFailure{"/particles/all/position/value has " + std::to_string(d[0]) + " frames; expected " + expected};
    for (auto* v : {&s.time, &s.kinetic, &s.potential, &s.total}) v->resize(s.frames);
    s.step.resize(s.frames);
    if (!s.patchOffset.empty()) {
      s.patchOffset.resize(s.frames);
      s.patchCount.resize(s.frames);
    }
    // what the last frame holds, for inspect
    if (const auto dt = readNumberAttr(f, "parameters", "dt")) s.dt = *dt;
    if (s.frames > 0) {
      const std::int64_t lastStep = s.step[s.frames - 1];
      if (H5Lexists(f, "breakage", H5P_DEFAULT) > 0) {
        const std::vector<std::int64_t> broke =
            readAll<std::int64_t>(f, "breakage/step", H5T_NATIVE_INT64, {H5T_INTEGER, 1, {}, "one step per broken connector, [N]"}, limit);
        s.breakages = static_cast<std::size_t>(std::count_if(broke.begin(), broke.end(), [&](std::int64_t k) { return k <= lastStep; }));
      }
      const Expect perBody{H5T_INTEGER, 1, {}, "one step per body, [B]"};
      const std::vector<std::int64_t> created = readAll<std::int64_t>(f, "particles/bodies/created", H5T_NATIVE_INT64, perBody, limit);
      const std::vector<std::int64_t> retired = readAll<std::int64_t>(f, "particles/bodies/retired", H5T_NATIVE_INT64, perBody, limit);
      for (std::size_t i = 0; i < std::min(created.size(), retired.size()); ++i)
        s.bodiesAlive += created[i] <= lastStep && (retired[i] < 0 || lastStep < retired[i]) ? 1 : 0;
      const auto last = [&](const char* name) -> std::int64_t {
        if (H5Lexists(f, name, H5P_DEFAULT) <= 0) return -1;
        const std::vector<std::int64_t> v = readAll<std::int64_t>(f, name, H5T_NATIVE_INT64, {H5T_INTEGER, 1, {}, "one count per frame, [T]"}, limit);
        return v.size() >= s.frames ? v[s.frames - 1] : -1;
      };
      if (H5Lexists(f, "observables", H5P_DEFAULT) > 0) {
        s.contacts = last("observables/contact_count/value");
        s.patches = last("observables/patch_count/value");
      }
    }
    if (H5Lexists(f, "connectors", H5P_DEFAULT) > 0 && H5Lexists(f, "connectors/lines_offset", H5P_DEFAULT) > 0) {
      std::vector<hsize_t> shape;
      openChecked(f, "connectors/particle_a", {H5T_INTEGER, 1, {}, "one particle index per connector, [C]"}, limit, shape);
      s.connectors = static_cast<std::size_t>(shape[0]);
      openChecked(f, "connectors/lines", {H5T_INTEGER, 2, {2}, "lines [N, 2]"}, limit, shape);
      const hsize_t rows = shape[0];
      s.connectorLineOffset =
          readAll<std::int64_t>(f, "connectors/lines_offset", H5T_NATIVE_INT64, {H5T_INTEGER, 1, {}, "one row number per frame, [T]"}, limit);
      frames("connectors/lines_offset", s.connectorLineOffset.size());
      s.connectorLineOffset.resize(s.frames);
      for (std::size_t i = 0; i < s.frames; ++i)
        if (s.connectorLineOffset[i] < 0 || static_cast<hsize_t>(s.connectorLineOffset[i]) + s.connectors > rows)
          throw ReadFailure{"/connectors/lines_offset[" + std::to_string(i) + "] is " + std::to_string(s.connectorLineOffset[i]) +
                            "; expected a row of /connectors/lines (" + std::to_string(rows) + " rows) with " +
                            std::to_string(s.connectors) + " rows from it"};
    }
    // what a trajectory must not hold: no frame, times that are not numbers or that go back
    if (s.frames == 0) throw ReadFailure{"the trajectory has no frames; expected at least the first (step 0)"};
    for (std::size_t i = 0; i < s.frames; ++i) {
      if (!std::isfinite(s.time[i]))
        throw ReadFailure{"/particles/all/position/time[" + std::to_string(i) + "] is not a finite number; expected a time in seconds"};
      if (i > 0 && (s.time[i] < s.time[i - 1] || s.step[i] <= s.step[i - 1]))
        throw ReadFailure{"frame " + std::to_string(i) + " (step " + std::to_string(s.step[i]) +
                          ") does not come after the frame before it; expected increasing steps and times"};
    }
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
  return s;
}

namespace {

Result<std::vector<Vec3>> vec3Row(hid_t file, const std::string& path, const std::string& name, std::size_t frame,
                                  std::uint64_t limit) {
  try {
    const std::vector<double> raw = readRow(file, name, frame, {H5T_FLOAT, 3, {3}, "vectors [T, N, 3]"}, limit);
    std::vector<Vec3> out(raw.size() / 3);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]);
    return out;
  } catch (const ReadFailure& e) {
    return Error{path, 0, 0, e.what};
  }
}

}  // namespace

Result<std::vector<Vec3>> H5mdReader::positions(std::size_t frame) const {
  return vec3Row(impl_->file, impl_->path, "particles/all/position/value", frame, impl_->limit);
}

Result<std::vector<Vec3>> H5mdReader::bodyPositions(std::size_t frame) const {
  return vec3Row(impl_->file, impl_->path, "particles/bodies/position/value", frame, impl_->limit);
}

Result<std::vector<Quat>> H5mdReader::bodyOrientations(std::size_t frame) const {
  try {
    const std::vector<double> raw =
        readRow(impl_->file, "particles/bodies/orientation/value", frame, {H5T_FLOAT, 3, {4}, "quaternions [T, B, 4]"}, impl_->limit);
    std::vector<Quat> out(raw.size() / 4);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = Quat(raw[4 * i], raw[4 * i + 1], raw[4 * i + 2], raw[4 * i + 3]);
    return out;
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
}

namespace {

/// The datasets below a checkpoint's group, by their paths in it.
herr_t collectDataset(hid_t group, const char* name, const H5L_info_t* info, void* out) {
  if (info->type != H5L_TYPE_HARD) return 0;
  H5O_info_t object;
  if (H5Oget_info_by_name(group, name, &object, H5P_DEFAULT) < 0) return -1;
  if (object.type == H5O_TYPE_DATASET) static_cast<std::vector<std::string>*>(out)->emplace_back(name);
  return 0;
}

/// One dataset of a checkpoint as an archive array: numbers of one of the archive's types, one or two
/// dimensions, stored whole and uncompressed (its size on disk is its size).
StateArchive::Array readStateArray(hid_t group, const std::string& name, std::uint64_t fileSize) {
  const std::string where = "/checkpoint/.../" + name;
  Handle ds(H5Dopen2(group, name.c_str(), H5P_DEFAULT), H5Dclose, "cannot open dataset " + where);
  Handle type(H5Dget_type(ds.get()), H5Tclose, "datatype of " + where);
  const H5T_class_t c = H5Tget_class(type.get());
  const std::size_t size = H5Tget_size(type.get());
  StateArchive::Array a;
  a.name = name;
  hid_t memType = H5T_NATIVE_DOUBLE;
  if (c == H5T_FLOAT && size == 8) a.type = StateArchive::Type::F64;
  else if (c == H5T_FLOAT && size == 4) { a.type = StateArchive::Type::F32; memType = H5T_NATIVE_FLOAT; }
  else if (c == H5T_INTEGER && size == 8 && H5Tget_sign(type.get()) == H5T_SGN_2) { a.type = StateArchive::Type::I64; memType = H5T_NATIVE_INT64; }
  else if (c == H5T_INTEGER && size == 4 && H5Tget_sign(type.get()) == H5T_SGN_NONE) { a.type = StateArchive::Type::U32; memType = H5T_NATIVE_UINT32; }
  else if (c == H5T_INTEGER && size == 1 && H5Tget_sign(type.get()) == H5T_SGN_NONE) { a.type = StateArchive::Type::U8; memType = H5T_NATIVE_UINT8; }
  else throw ReadFailure{where + " holds values of a type no checkpoint has"};
  const std::vector<hsize_t> d = dims(ds.get());
  if (d.empty() || d.size() > 2 || (d.size() == 2 && d[1] == 0))
    throw ReadFailure{where + " has shape " + shapeText(d) + "; expected [n] or [n, k]"};
  a.width = d.size() == 2 ? static_cast<std::size_t>(d[1]) : 1;
  const long double bytes = static_cast<long double>(d[0]) * static_cast<long double>(a.width) * static_cast<long double>(size);
  Handle plist(H5Dget_create_plist(ds.get()), H5Pclose, "creation properties of " + where);
  const H5D_layout_t layout = H5Pget_layout(plist.get());
  if (bytes > static_cast<long double>(fileSize) || (layout != H5D_CONTIGUOUS && layout != H5D_COMPACT) ||
      (bytes > 0 && static_cast<long double>(H5Dget_storage_size(ds.get())) != bytes))
    throw ReadFailure{where + " claims shape " + shapeText(d) + ", which is not stored whole in the file"};
  a.bytes.resize(static_cast<std::size_t>(bytes));
  if (!a.bytes.empty() && H5Dread(ds.get(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, a.bytes.data()) < 0)
    throw ReadFailure{"cannot read " + where};
  return a;
}

}  // namespace

Result<Checkpoint> H5mdReader::checkpoint() const {
  const hid_t f = impl_->file;
  const std::uint64_t limit = impl_->limit;
  Checkpoint cp;
  try {
    const std::optional<std::int64_t> step = readCountAttr(f, "checkpoint", "step");
    if (!step || *step < 0)
      return Error{impl_->path, 0, 0, "the trajectory has no checkpoint (write one with volpar run --checkpoint-every STEPS)"};
    cp.step = *step;
    const std::optional<std::int64_t> slot = readCountAttr(f, "checkpoint", "slot");
    if (!slot || (*slot != 0 && *slot != 1)) throw ReadFailure{"/checkpoint@slot is missing or neither 0 nor 1"};
    const std::string name = "checkpoint/slot_" + std::to_string(*slot);
    if (H5Lexists(f, name.c_str(), H5P_DEFAULT) <= 0)
      throw ReadFailure{"/checkpoint@slot is " + std::to_string(*slot) + " but there is no /" + name};
    const std::optional<std::int64_t> slotStep = readCountAttr(f, name, "step");
    if (!slotStep || *slotStep != cp.step)
      throw ReadFailure{"/" + name + "@step is not /checkpoint@step (" + std::to_string(cp.step) + ")"};
    cp.sceneFile = readStringAttr(f, "parameters", "scene_file", limit);
    cp.sceneText = readStrings(f, "parameters/scene", true, limit).at(0);
    const std::optional<std::int64_t> seed = readCountAttr(f, "parameters", "seed");
    const std::optional<std::int64_t> every = readCountAttr(f, "parameters", "output_every");
    const std::optional<std::int64_t> end = readCountAttr(f, name, "end_step");
    if (!seed || !every || !end || *every < 1 || *every > std::numeric_limits<int>::max() || *end < cp.step)
      throw ReadFailure{"/parameters@seed, /parameters@output_every or /" + name + "@end_step is missing or out of range"};
    cp.seed = *seed;
    cp.outputEvery = static_cast<int>(*every);
    cp.endStep = *end;
    Handle group(H5Gopen2(f, name.c_str(), H5P_DEFAULT), H5Gclose, "cannot open /" + name);
    std::vector<std::string> names;
    if (H5Lvisit(group.get(), H5_INDEX_NAME, H5_ITER_INC, collectDataset, &names) < 0)
      throw ReadFailure{"cannot list /" + name};
    constexpr std::size_t kMaxArrays = 1024;
    if (names.size() > kMaxArrays) throw ReadFailure{"/" + name + " holds " + std::to_string(names.size()) + " datasets; a checkpoint has fewer than " + std::to_string(kMaxArrays)};
    for (const std::string& n : names) cp.state.add(readStateArray(group.get(), n, impl_->fileSize));
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
  return cp;
}


// ---- reads for volpar render

namespace {

/// Rows first .. first + n - 1 of an [N] or [N, k] dataset as doubles, after checking it against `e`.
std::vector<double> readRange(hid_t file, const std::string& name, std::uint64_t first, std::uint64_t n, const Expect& e,
                              std::uint64_t limit) {
  std::vector<hsize_t> d;
  const Handle ds = openChecked(file, name, e, limit, d);
  if (first > d[0] || n > d[0] - first)
    throw ReadFailure{"rows " + std::to_string(first) + " to " + std::to_string(first + n) + " (exclusive) are past the end of /" +
                      name + ", which has " + std::to_string(d[0]) + " rows; expected " + e.what};
  std::vector<hsize_t> start(d.size(), 0), count = d;
  start[0] = first;
  count[0] = n;
  std::vector<double> out(elements(count));
  if (out.empty()) return out;
  Handle fileSpace(H5Dget_space(ds.get()), H5Sclose, "dataspace");
  if (H5Sselect_hyperslab(fileSpace.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr) < 0)
    throw ReadFailure{"cannot select rows of /" + name};
  Handle memSpace(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr), H5Sclose, "dataspace");
  if (H5Dread(ds.get(), H5T_NATIVE_DOUBLE, memSpace.get(), fileSpace.get(), H5P_DEFAULT, out.data()) < 0)
    throw ReadFailure{"cannot read /" + name};
  return out;
}

/// Whole numbers of a [N] integer dataset, each from `lo` to `hi`.
std::vector<std::int64_t> readIndices(hid_t file, const std::string& name, std::int64_t lo, std::int64_t hi, const std::string& what,
                                      std::uint64_t limit) {
  std::vector<std::int64_t> v = readAll<std::int64_t>(file, name, H5T_NATIVE_INT64, {H5T_INTEGER, 1, {}, what.c_str()}, limit);
  for (std::size_t i = 0; i < v.size(); ++i)
    if (v[i] < lo || v[i] > hi)
      throw ReadFailure{"/" + name + "[" + std::to_string(i) + "] is " + std::to_string(v[i]) + "; expected " + what + ", from " +
                        std::to_string(lo) + " to " + std::to_string(hi)};
  return v;
}

/// Vectors [N, 3] as Vec3, each finite.
std::vector<Vec3> toVec3(const std::vector<double>& raw, const std::string& name) {
  std::vector<Vec3> out(raw.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = Vec3(raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]);
    if (!out[i].allFinite()) throw ReadFailure{"/" + name + " row " + std::to_string(i) + " is not finite; expected finite vectors"};
  }
  return out;
}

/// The rows of frame t of a ragged group (/contacts, /patches): its offset and count there, checked.
std::pair<std::uint64_t, std::uint64_t> raggedRows(hid_t file, const std::string& group, std::size_t frame, std::uint64_t limit) {
  if (H5Lexists(file, group.c_str(), H5P_DEFAULT) <= 0) throw ReadFailure{"missing group /" + group + " (ragged rows per frame)"};
  const Expect perFrame{H5T_INTEGER, 1, {}, "one row number per frame, [T]"};
  const double offset = readRow(file, group + "/offset", frame, perFrame, limit).at(0);
  const double count = readRow(file, group + "/count", frame, perFrame, limit).at(0);
  if (!(offset >= 0.0) || !(count >= 0.0) || offset > 9.0e15 || count > 9.0e15)
    throw ReadFailure{"/" + group + "/offset or /" + group + "/count of frame " + std::to_string(frame) +
                      " is negative or too large; expected a row range"};
  return {static_cast<std::uint64_t>(offset), static_cast<std::uint64_t>(count)};
}

}  // namespace

Result<std::vector<double>> H5mdReader::radii() const {
  try {
    const std::string name = "particles/all/radius";
    std::vector<double> r = readAll<double>(impl_->file, name, H5T_NATIVE_DOUBLE, {H5T_FLOAT, 1, {}, "one radius per particle, [P]"}, impl_->limit);
    for (std::size_t i = 0; i < r.size(); ++i)
      if (!std::isfinite(r[i]) || !(r[i] > 0.0) || r[i] > 1e9)
        throw ReadFailure{"/" + name + "[" + std::to_string(i) + "] is " + std::to_string(r[i]) + "; expected a radius above 0 and at most 1e9 m"};
    return r;
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
}

Result<std::vector<std::array<double, 4>>> H5mdReader::planes() const {
  try {
    const std::string name = "parameters/planes";
    const std::vector<double> raw = readAll<double>(impl_->file, name, H5T_NATIVE_DOUBLE, {H5T_FLOAT, 2, {4}, "planes [n, 4]: normal and offset"}, impl_->limit);
    std::vector<std::array<double, 4>> out(raw.size() / 4);
    for (std::size_t i = 0; i < out.size(); ++i) {
      for (std::size_t k = 0; k < 4; ++k) out[i][k] = raw[4 * i + k];
      const double n = std::sqrt(out[i][0] * out[i][0] + out[i][1] * out[i][1] + out[i][2] * out[i][2]);
      if (!std::isfinite(n) || !std::isfinite(out[i][3]) || std::abs(n - 1.0) > 1e-6 || std::abs(out[i][3]) > 1e9)
        throw ReadFailure{"/" + name + " row " + std::to_string(i) + " is not a unit normal and an offset within 1e9 m; expected planes [n, 4]"};
    }
    return out;
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
}

Result<std::vector<std::string>> H5mdReader::bodyKinds() const {
  try {
    return readStrings(impl_->file, "particles/bodies/kind", false, impl_->limit);
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
}

Result<std::vector<std::int32_t>> H5mdReader::particleBodies(std::size_t frame, std::size_t bodies) const {
  try {
    const std::string name = "particles/all/body/value";
    const std::size_t particles = readAll<double>(impl_->file, "particles/all/radius", H5T_NATIVE_DOUBLE,
                                                  {H5T_FLOAT, 1, {}, "one radius per particle, [P]"}, impl_->limit).size();
    const std::vector<double> raw =
        readRow(impl_->file, name, frame, {H5T_INTEGER, 2, {static_cast<hsize_t>(particles)}, "body indices [T, P] (int32)"}, impl_->limit);
    std::vector<std::int32_t> out(raw.size());
    for (std::size_t i = 0; i < raw.size(); ++i) {
      if (!(raw[i] >= 0.0) || !(raw[i] < static_cast<double>(bodies)))
        throw ReadFailure{"/" + name + " frame " + std::to_string(frame) + " particle " + std::to_string(i) + " has body " +
                          std::to_string(static_cast<long long>(std::clamp(raw[i], -9e18, 9e18))) + "; expected a body index from 0 to " +
                          std::to_string(static_cast<long long>(bodies) - 1)};
      out[i] = static_cast<std::int32_t>(raw[i]);
    }
    return out;
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
}

bool H5mdReader::hasConnectors() const { return H5Lexists(impl_->file, "connectors", H5P_DEFAULT) > 0; }

Result<ConnectorTable> H5mdReader::connectors(std::size_t particles) const {
  const hid_t f = impl_->file;
  const std::uint64_t limit = impl_->limit;
  ConnectorTable t;
  try {
    if (H5Lexists(f, "connectors", H5P_DEFAULT) <= 0)
      throw ReadFailure{"the trajectory has no /connectors group (written by newer versions of volpar run); expected particle_a, "
                        "particle_b and kind [C]"};
    const auto p = static_cast<std::int64_t>(particles) - 1;
    const std::vector<std::int64_t> a = readIndices(f, "connectors/particle_a", 0, p, "particle indices [C]", limit);
    const std::vector<std::int64_t> b = readIndices(f, "connectors/particle_b", 0, p, "particle indices [C]", limit);
    const std::vector<std::int64_t> kind = readIndices(f, "connectors/kind", 0, 2, "connector kinds [C] (0 rod, 1 spring, 2 bond)", limit);
    if (b.size() != a.size() || kind.size() != a.size())
      throw ReadFailure{"/connectors/particle_a, particle_b and kind have " + std::to_string(a.size()) + ", " + std::to_string(b.size()) +
                        " and " + std::to_string(kind.size()) + " entries; expected one each per connector"};
    t.particleA.assign(a.begin(), a.end());
    t.particleB.assign(b.begin(), b.end());
    t.kind.assign(kind.begin(), kind.end());
    t.breakStep.assign(a.size(), std::numeric_limits<std::int64_t>::max());
    if (H5Lexists(f, "breakage", H5P_DEFAULT) > 0) {
      const auto c = static_cast<std::int64_t>(a.size()) - 1;
      const std::vector<std::int64_t> which = readIndices(f, "breakage/connector", 0, c, "connector indices [N]", limit);
      const std::vector<std::int64_t> step =
          readIndices(f, "breakage/step", 0, std::numeric_limits<std::int64_t>::max(), "break steps [N]", limit);
      if (step.size() != which.size())
        throw ReadFailure{"/breakage/connector and /breakage/step have " + std::to_string(which.size()) + " and " +
                          std::to_string(step.size()) + " entries; expected one each per event"};
      for (std::size_t i = 0; i < which.size(); ++i) {
        std::int64_t& s = t.breakStep[static_cast<std::size_t>(which[i])];
        s = std::min(s, step[i]);
      }
    }
    // connectors broken before the first frame (a resumed run's file)
    if (H5Lexists(f, "connectors/broken_before", H5P_DEFAULT) > 0) {
      const std::vector<std::int64_t> before = readIndices(f, "connectors/broken_before", 0, 1, "0 or 1 per connector [C]", limit);
      if (before.size() != a.size())
        throw ReadFailure{"/connectors/broken_before has " + std::to_string(before.size()) + " entries; expected " +
                          std::to_string(a.size()) + ", one per connector"};
      for (std::size_t i = 0; i < before.size(); ++i)
        if (before[i] != 0) t.breakStep[i] = std::numeric_limits<std::int64_t>::min();
    }
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
  return t;
}

Result<FrameRows> H5mdReader::contactPoints(std::size_t frame) const {
  try {
    const auto [first, n] = raggedRows(impl_->file, "contacts", frame, impl_->limit);
    FrameRows rows;
    rows.point = toVec3(readRange(impl_->file, "contacts/point", first, n, {H5T_FLOAT, 2, {3}, "contact points [N, 3]"}, impl_->limit),
                        "contacts/point");
    return rows;
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
}

Result<FrameRows> H5mdReader::patchNormals(std::size_t frame) const {
  try {
    const auto [first, n] = raggedRows(impl_->file, "patches", frame, impl_->limit);
    FrameRows rows;
    rows.point = toVec3(readRange(impl_->file, "patches/point", first, n, {H5T_FLOAT, 2, {3}, "patch points [N, 3]"}, impl_->limit),
                        "patches/point");
    rows.normal = toVec3(readRange(impl_->file, "patches/normal", first, n, {H5T_FLOAT, 2, {3}, "patch normals [N, 3]"}, impl_->limit),
                         "patches/normal");
    return rows;
  } catch (const ReadFailure& e) {
    return Error{impl_->path, 0, 0, e.what};
  }
}

}  // namespace volpar
