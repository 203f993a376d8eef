#include "volpar/engine/io/h5md_writer.hpp"

#include <hdf5.h>
#include <sys/resource.h>
#include <sys/statvfs.h>

#include <array>
#include <chrono>
#include <limits>
#include <cstdlib>
#include <filesystem>
#include <set>

#include "volpar/engine/core/input_file.hpp"
#include "volpar/engine/core/limits.hpp"
#include "volpar/engine/core/version.hpp"
#include "volpar/engine/io/xdmf_writer.hpp"

namespace volpar {

namespace {

// HDF5 closes whatever is still open when the process exits; after a close that failed (a full disk) its
// own exit handler crashes. Every file here is closed explicitly, so that handler is not wanted (it must be
// declined before the library's first use, hence at static initialisation).
[[maybe_unused]] const bool kHdf5NoExitHandler = H5dont_atexit() >= 0;

/// Bytes a file of `size` bytes at `path` may still grow by: the least of its disk's free space and the
/// process's file-size limit (ulimit -f).
std::uint64_t roomToGrow(const std::string& path, std::uint64_t size) {
  std::uint64_t room = std::numeric_limits<std::uint64_t>::max();
  struct rlimit limit {};
  if (getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY)
    room = limit.rlim_cur > size ? static_cast<std::uint64_t>(limit.rlim_cur) - size : 0;
  struct statvfs disk {};
  if (statvfs(path.c_str(), &disk) == 0)
    room = std::min<std::uint64_t>(room, static_cast<std::uint64_t>(disk.f_bavail) * disk.f_frsize);
  return room;
}

/// Owns an HDF5 identifier.
class Hid {
 public:
  Hid() = default;
  Hid(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  Hid(Hid&& o) noexcept : id_(o.id_), close_(o.close_) { o.id_ = H5I_INVALID_HID; }
  Hid& operator=(Hid&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = o.id_;
      close_ = o.close_;
      o.id_ = H5I_INVALID_HID;
    }
    return *this;
  }
  Hid(const Hid&) = delete;
  Hid& operator=(const Hid&) = delete;
  ~Hid() { reset(); }
  void reset() {
    if (id_ >= 0 && close_) close_(id_);
    id_ = H5I_INVALID_HID;
  }
  [[nodiscard]] hid_t get() const { return id_; }
  [[nodiscard]] bool valid() const { return id_ >= 0; }
  /// Gives up ownership (the caller closes it and checks the result).
  [[nodiscard]] hid_t release() {
    const hid_t id = id_;
    id_ = H5I_INVALID_HID;
    return id;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
  herr_t (*close_)(hid_t) = nullptr;
};

/// How this process writes the file: alone, or as one of several processes writing it together with parallel
/// HDF5 (MPI-IO). With several, every write is a collective call of every process: each writes its share of
/// the block's rows (writeBlock), or process 0 the whole of a block that cannot be divided.
struct Io {
  int rank = 0;
  int size = 1;
  Hid transfer;            ///< the dataset transfer property list: collective MPI-IO with several processes
  std::uint64_t bytes = 0; ///< bytes this process has written into datasets
  [[nodiscard]] hid_t transferList() const { return transfer.valid() ? transfer.get() : H5P_DEFAULT; }
  [[nodiscard]] bool lead() const { return rank == 0; }
};

/// Thrown inside this file only, turned into an Error at the public boundary.
struct H5Failure {
  std::string what;
};

void check(herr_t status, const std::string& what) {
  if (status < 0) throw H5Failure{what};
}

Hid checked(hid_t id, herr_t (*close)(hid_t), const std::string& what) {
  if (id < 0) throw H5Failure{what};
  return Hid(id, close);
}

/// Writes `data`, a block of `count` elements (C order), at `start` of the dataset `ds`. With several
/// processes (a collective call of each, with the same block) each writes a share of the block: its rows, or
/// where the block is one row deep, its entries along the next dimension, divided at the dataset's chunk
/// boundaries (`chunk`; empty: contiguous) so that no two processes write one chunk; a block one element deep
/// in both, or a scalar (empty `count`), process 0 writes whole.
void writeBlock(Io& io, hid_t ds, hid_t memType, const std::vector<hsize_t>& start, const std::vector<hsize_t>& count,
                const std::vector<hsize_t>& chunk, const void* data, const std::string& what) {
  const bool scalar = count.empty();
  Hid fileSpace = checked(H5Dget_space(ds), H5Sclose, "dataset space of " + what);
  Hid memSpace = scalar ? checked(H5Screate(H5S_SCALAR), H5Sclose, "space")
                        : checked(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr), H5Sclose, "space");
  hsize_t elements = 1;
  for (const hsize_t c : count) elements *= c;
  if (elements == 0) return;  // (every process alike)
  std::vector<hsize_t> myStart = start, myCount = count, memStart(count.size(), 0);
  bool mine = true;
  if (io.size > 1) {
    std::size_t d = 0;
    while (d < count.size() && d < 2 && count[d] <= 1) ++d;
    if (d < count.size() && d < 2) {
      // the block's extent along d in units that end at chunk boundaries (the first and last may be partial)
      const hsize_t k = d < chunk.size() && chunk[d] > 0 ? chunk[d] : 1;
      const hsize_t lo = start[d], hi = start[d] + count[d];
      const hsize_t first = lo / k, units = (hi + k - 1) / k - first;
      const auto at = [&](hsize_t u) { return std::clamp((first + u) * k, lo, hi); };
      const auto r = static_cast<hsize_t>(io.rank), n = static_cast<hsize_t>(io.size);
      const hsize_t from = at(units * r / n), to = at(units * (r + 1) / n);
      mine = to > from;
      myStart[d] = from;
      myCount[d] = to - from;
      memStart[d] = from - lo;
    } else {
      mine = io.lead();
    }
  }
  if (!mine) {
    check(H5Sselect_none(fileSpace.get()), "select");
    check(H5Sselect_none(memSpace.get()), "select");
  } else if (!scalar) {
    check(H5Sselect_hyperslab(fileSpace.get(), H5S_SELECT_SET, myStart.data(), nullptr, myCount.data(), nullptr), "select");
    check(H5Sselect_hyperslab(memSpace.get(), H5S_SELECT_SET, memStart.data(), nullptr, myCount.data(), nullptr), "select");
  }
  check(H5Dwrite(ds, memType, memSpace.get(), fileSpace.get(), io.transferList(), data), "write " + what);
  if (mine) {
    hsize_t written = 1;
    for (const hsize_t c : myCount) written *= c;
    io.bytes += written * H5Tget_size(memType);
  }
}

/// The group `name` (a path of groups; those missing on the way are made too), without modification times
/// so that identical runs give identical files (HDF5 makes intermediate groups with its default properties,
/// which record times: each group on the way is made here instead).
Hid group(hid_t parent, const std::string& name) {
  Hid gcpl = checked(H5Pcreate(H5P_GROUP_CREATE), H5Pclose, "group property list");
  check(H5Pset_obj_track_times(gcpl.get(), 0), "track times");
  for (std::size_t slash = name.find('/'); slash != std::string::npos; slash = name.find('/', slash + 1)) {
    const std::string way = name.substr(0, slash);
    if (H5Lexists(parent, way.c_str(), H5P_DEFAULT) > 0) continue;
    checked(H5Gcreate2(parent, way.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose, "group " + way);
  }
  return checked(H5Gcreate2(parent, name.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose, "group " + name);
}

/// Dataset creation properties: no modification times, so identical runs give identical files.
Hid datasetPlist() {
  Hid dcpl = checked(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, "dataset property list");
  check(H5Pset_obj_track_times(dcpl.get(), 0), "track times");
  return dcpl;
}

Hid vlenString() {
  Hid t = checked(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
  check(H5Tset_size(t.get(), H5T_VARIABLE), "string size");
  check(H5Tset_cset(t.get(), H5T_CSET_UTF8), "string charset");
  return t;
}

/// Fixed-length UTF-8 strings of `width` bytes, padded with zero bytes (datasets of strings are written so:
/// parallel HDF5 cannot write variable-length data).
Hid fixedString(std::size_t width) {
  Hid t = checked(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
  check(H5Tset_size(t.get(), std::max<std::size_t>(width, 1)), "string size");
  check(H5Tset_strpad(t.get(), H5T_STR_NULLPAD), "string pad");
  check(H5Tset_cset(t.get(), H5T_CSET_UTF8), "string charset");
  return t;
}

/// `values` side by side in `width` bytes each (a value longer than that is a failure, never cut short).
std::string padded(const std::vector<std::string>& values, std::size_t width, const std::string& what) {
  width = std::max<std::size_t>(width, 1);
  std::string buf(values.size() * width, '\0');
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (values[i].size() > width)
      throw H5Failure{what + ": '" + values[i] + "' is longer than the " + std::to_string(width) + " bytes kept for it"};
    values[i].copy(&buf[i * width], values[i].size());
  }
  return buf;
}

void attrString(hid_t obj, const std::string& name, const std::string& value) {
  Hid type = vlenString();
  Hid space = checked(H5Screate(H5S_SCALAR), H5Sclose, "scalar space");
  Hid attr = checked(H5Acreate2(obj, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                     "attribute " + name);
  const char* p = value.c_str();
  check(H5Awrite(attr.get(), type.get(), &p), "attribute " + name);
}

/// Array of variable-length UTF-8 strings as an attribute (the names of an enum's values, in order).
void attrStrings(hid_t obj, const std::string& name, const std::vector<std::string>& values) {
  Hid type = vlenString();
  const hsize_t n = values.size();
  Hid space = checked(H5Screate_simple(1, &n, nullptr), H5Sclose, "space");
  Hid attr = checked(H5Acreate2(obj, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                     "attribute " + name);
  std::vector<const char*> ptrs;
  for (const auto& v : values) ptrs.push_back(v.c_str());
  if (n > 0) check(H5Awrite(attr.get(), type.get(), ptrs.data()), "attribute " + name);
}

template <class T>
hid_t nativeType();
template <>
hid_t nativeType<double>() { return H5T_NATIVE_DOUBLE; }
template <>
hid_t nativeType<std::int32_t>() { return H5T_NATIVE_INT32; }
template <>
hid_t nativeType<std::int64_t>() { return H5T_NATIVE_INT64; }
template <>
hid_t nativeType<std::int8_t>() { return H5T_NATIVE_INT8; }

template <class T>
hid_t fileType();
template <>
hid_t fileType<double>() { return H5T_IEEE_F64LE; }
template <>
hid_t fileType<std::int32_t>() { return H5T_STD_I32LE; }
template <>
hid_t fileType<std::int64_t>() { return H5T_STD_I64LE; }
template <>
hid_t fileType<std::int8_t>() { return H5T_STD_I8LE; }

template <class T>
void attrArray(hid_t obj, const std::string& name, const std::vector<T>& values) {
  const hsize_t n = values.size();
  Hid space = checked(H5Screate_simple(1, &n, nullptr), H5Sclose, "space");
  Hid attr = checked(H5Acreate2(obj, name.c_str(), fileType<T>(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                     "attribute " + name);
  check(H5Awrite(attr.get(), nativeType<T>(), values.data()), "attribute " + name);
}

template <class T>
void attrScalar(hid_t obj, const std::string& name, T value) {
  Hid space = checked(H5Screate(H5S_SCALAR), H5Sclose, "scalar space");
  Hid attr = checked(H5Acreate2(obj, name.c_str(), fileType<T>(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                     "attribute " + name);
  check(H5Awrite(attr.get(), nativeType<T>(), &value), "attribute " + name);
}

/// Fixed-length string array attribute (H5MD box/boundary).
void attrFixedStrings(hid_t obj, const std::string& name, const std::vector<std::string>& values, std::size_t len) {
  Hid type = checked(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
  check(H5Tset_size(type.get(), len), "string size");
  check(H5Tset_strpad(type.get(), H5T_STR_NULLPAD), "string pad");
  std::string buf(values.size() * len, '\0');
  for (std::size_t i = 0; i < values.size(); ++i) values[i].copy(&buf[i * len], std::min(len, values[i].size()));
  const hsize_t n = values.size();
  Hid space = checked(H5Screate_simple(1, &n, nullptr), H5Sclose, "space");
  Hid attr = checked(H5Acreate2(obj, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                     "attribute " + name);
  check(H5Awrite(attr.get(), type.get(), buf.data()), "attribute " + name);
}

Hid chunkedPlist(const std::vector<hsize_t>& chunk) {
  Hid dcpl = datasetPlist();
  check(H5Pset_chunk(dcpl.get(), static_cast<int>(chunk.size()), chunk.data()), "chunk");
  return dcpl;
}

Hid compressedPlist(const std::vector<hsize_t>& chunk) {
  Hid dcpl = chunkedPlist(chunk);
  check(H5Pset_shuffle(dcpl.get()), "shuffle");
  check(H5Pset_deflate(dcpl.get(), 1), "deflate");
  return dcpl;
}

/// Time-independent dataset with dims `dims`.
template <class T>
void dataset(Io& io, hid_t parent, const std::string& name, const std::vector<hsize_t>& dims, const T* data,
             const std::string& unit = "") {
  Hid space = checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose, "space");
  hsize_t total = 1;
  for (const hsize_t d : dims) total *= d;
  std::vector<hsize_t> chunk = dims;
  if (!chunk.empty()) chunk[0] = std::min<hsize_t>(dims[0], 65536);
  Hid dcpl = total > 0 ? compressedPlist(chunk) : datasetPlist();
  Hid ds = checked(H5Dcreate2(parent, name.c_str(), fileType<T>(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                   H5Dclose, "dataset " + name);
  writeBlock(io, ds.get(), nativeType<T>(), std::vector<hsize_t>(dims.size(), 0), dims, chunk, data, name);
  if (!unit.empty()) attrString(ds.get(), "unit", unit);
}

/// A list of strings, each as wide as the longest.
void stringDataset(Io& io, hid_t parent, const std::string& name, const std::vector<std::string>& values) {
  std::size_t width = 1;
  for (const std::string& v : values) width = std::max(width, v.size());
  Hid type = fixedString(width);
  const hsize_t n = values.size();
  Hid space = checked(H5Screate_simple(1, &n, nullptr), H5Sclose, "space");
  Hid dcpl = datasetPlist();
  Hid ds = checked(H5Dcreate2(parent, name.c_str(), type.get(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                   H5Dclose, "dataset " + name);
  const std::string buf = padded(values, width, name);
  writeBlock(io, ds.get(), type.get(), {0}, {n}, {}, buf.data(), name);
}

/// One string, in a string type of its own length.
void scalarString(Io& io, hid_t parent, const std::string& name, const std::string& value) {
  Hid type = fixedString(value.size());
  Hid space = checked(H5Screate(H5S_SCALAR), H5Sclose, "scalar space");
  Hid dcpl = datasetPlist();
  Hid ds = checked(H5Dcreate2(parent, name.c_str(), type.get(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                   H5Dclose, "dataset " + name);
  const std::string buf = padded({value}, value.size(), name);
  writeBlock(io, ds.get(), type.get(), {}, {}, {}, buf.data(), name);
}

/// An extendible dataset [T, tail...], grown one row per frame.
class Series {
 public:
  Series() = default;
  /// With `growTo` > 0, the first dimension after the frames can grow too, up to `growTo` (bodies appear
  /// when bodies break); entries not written yet read as NaN (floating-point data). The bound keeps the frames
  /// the only unlimited dimension, so that HDF5 indexes the chunks in an extensible array, which appending
  /// never rearranges (two unlimited dimensions take a B-tree, whose node splits rewrite nodes that hold
  /// frames already counted complete; a run killed in the middle of a split lost them).
  Series(Io& io, hid_t parent, const std::string& name, hid_t type, std::vector<hsize_t> tail, hsize_t growTo = 0)
      : io_(&io), name_(name), tail_(std::move(tail)), growTo_(growTo) {
    const bool growable = growTo > 0;
    std::vector<hsize_t> dims{0}, maxdims{H5S_UNLIMITED}, chunk{1};
    hsize_t rowSize = 1;
    for (std::size_t k = 0; k < tail_.size(); ++k) {
      dims.push_back(tail_[k]);
      maxdims.push_back(growable && k == 0 ? std::max(growTo, tail_[k]) : tail_[k]);
      rowSize *= tail_[k];
    }
    // Small chunks: the file is flushed after every frame, which recompresses the partly filled last
    // chunk, so a chunk holds at most 8 KiB of small rows (several frames) or 64 KiB of one big row.
    constexpr hsize_t kSmallRow = 1024;
    constexpr hsize_t kBigChunk = 8192;
    if (rowSize == 0) {
      chunk.assign(dims.size(), 1);
    } else if (rowSize <= kSmallRow) {
      chunk[0] = kSmallRow / rowSize;
      for (const hsize_t d : tail_) chunk.push_back(d);
    } else {
      chunk.push_back(std::clamp<hsize_t>(kBigChunk / (rowSize / tail_[0]), 1, tail_[0]));
      for (std::size_t k = 1; k < tail_.size(); ++k) chunk.push_back(tail_[k]);
    }
    // bodies appear over a run: chunks 64 bodies wide, whatever the count at the start
    if (growable && !tail_.empty()) {
      hsize_t row = 1;
      for (std::size_t k = 1; k < tail_.size(); ++k) row *= tail_[k];
      chunk[1] = std::min<hsize_t>(64, maxdims[1]);  // (no wider than the dimension can grow)
      chunk[0] = std::max<hsize_t>(1, kSmallRow / (chunk[1] * row));
    }
    for (hsize_t& c : chunk) c = std::max<hsize_t>(c, 1);
    chunk_ = chunk;
    Hid space = checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), maxdims.data()), H5Sclose, "space");
    // A chunk that one append fills is written once, compressed. A chunk that fills over several appends is
    // rewritten each time: uncompressed, so it keeps its place in the file. (A compressed chunk that grows
    // moves, HDF5 reuses its old space, and a run killed before the next flush would leave the frames
    // already counted complete pointing at overwritten bytes.)
    const bool writtenOnce = chunk[0] == 1 && !growable;
    Hid dcpl = writtenOnce ? compressedPlist(chunk) : chunkedPlist(chunk);
    if (H5Tget_class(type) == H5T_FLOAT) {
      const double nan = std::numeric_limits<double>::quiet_NaN();
      check(H5Pset_fill_value(dcpl.get(), H5T_NATIVE_DOUBLE, &nan), "fill value");
    }
    // Appended, never read back: a cache of two chunks (the one being filled and the one before) is enough.
    // HDF5's default, 1 MiB per dataset, made a long run's memory climb by tens of MiB before it levelled.
    hsize_t chunkBytes = H5Tget_size(type);
    for (const hsize_t c : chunk) chunkBytes *= c;
    Hid dapl = checked(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose, "dataset access property list");
    check(H5Pset_chunk_cache(dapl.get(), 11, static_cast<std::size_t>(2 * chunkBytes), 1.0), "chunk cache");
    ds_ = checked(H5Dcreate2(parent, name.c_str(), type, space.get(), H5P_DEFAULT, dcpl.get(), dapl.get()), H5Dclose,
                  "dataset " + name);
  }

  [[nodiscard]] hid_t id() const { return ds_.get(); }

  void append(hid_t memType, const void* data) { appendRows(memType, data, 1); }

  /// Appends `n` rows at once (ragged per-frame data).
  void appendRows(hid_t memType, const void* data, hsize_t n) {
    if (n == 0) return;
    std::vector<hsize_t> dims{rows_ + n};
    for (const hsize_t d : tail_) dims.push_back(d);
    check(H5Dset_extent(ds_.get(), dims.data()), "extend dataset");
    std::vector<hsize_t> start(dims.size(), 0), count = dims;
    start[0] = rows_;
    count[0] = n;
    writeBlock(*io_, ds_.get(), memType, start, count, chunk_, data, name_);
    rows_ += n;
  }
  [[nodiscard]] hsize_t rows() const { return rows_; }

  /// Grows the first dimension after the frames to `n` (growable series only); earlier frames read NaN there.
  void growTail(hsize_t n) {
    if (n <= tail_[0]) return;
    if (n > growTo_)
      throw H5Failure{"the trajectory has room for " + std::to_string(growTo_) + " bodies and the world has " +
                      std::to_string(n)};
    tail_[0] = n;
    std::vector<hsize_t> dims{rows_};
    for (const hsize_t d : tail_) dims.push_back(d);
    check(H5Dset_extent(ds_.get(), dims.data()), "grow dataset");
  }

  /// Overwrites element `i` of a one-dimensional series.
  void writeAt(hsize_t i, hid_t memType, const void* data) { writeBlock(*io_, ds_.get(), memType, {i}, {1}, chunk_, data, name_); }

 private:
  Io* io_ = nullptr;
  std::string name_;
  std::vector<hsize_t> chunk_;
  Hid ds_;
  std::vector<hsize_t> tail_;
  hsize_t growTo_ = 0;
  hsize_t rows_ = 0;
};

/// An H5MD time-dependent element: {value [T, ...], step [T], time [T]}.
class Element {
 public:
  Element() = default;
  /// With `clock` given, step and time are hard links to that element's (H5MD allows sharing them
  /// between elements sampled together), and append() leaves them to the owner.
  Element(Io& io, hid_t parent, const std::string& name, hid_t type, std::vector<hsize_t> tail, const std::string& unit,
          const Element* clock = nullptr, hsize_t growTo = 0) {
    group_ = group(parent, name);
    value_ = Series(io, group_.get(), "value", type, std::move(tail), growTo);
    if (!unit.empty()) attrString(value_.id(), "unit", unit);
    if (clock) {
      check(H5Lcreate_hard(clock->group_.get(), "step", group_.get(), "step", H5P_DEFAULT, H5P_DEFAULT), "link step");
      check(H5Lcreate_hard(clock->group_.get(), "time", group_.get(), "time", H5P_DEFAULT, H5P_DEFAULT), "link time");
      ownsClock_ = false;
      return;
    }
    step_ = Series(io, group_.get(), "step", H5T_STD_I64LE, {});
    time_ = Series(io, group_.get(), "time", H5T_IEEE_F64LE, {});
    attrString(time_.id(), "unit", "s");
  }
  void growTail(hsize_t n) { value_.growTail(n); }
  void append(hid_t memType, const void* data, std::int64_t step, double time) {
    value_.append(memType, data);
    if (!ownsClock_) return;
    step_.append(H5T_NATIVE_INT64, &step);
    time_.append(H5T_NATIVE_DOUBLE, &time);
  }

 private:
  Hid group_;
  Series value_, step_, time_;
  bool ownsClock_ = true;
};

void writeBox(hid_t particlesGroup) {
  Hid box = group(particlesGroup, "box");
  attrScalar<std::int32_t>(box.get(), "dimension", 3);
  attrFixedStrings(box.get(), "boundary", {"none", "none", "none"}, 4);
}

std::string kindName(BodyKind k) {
  switch (k) {
    case BodyKind::Rigid: return "rigid";
    case BodyKind::Deformable: return "deformable";
    case BodyKind::Static: return "static";
  }
  return "unknown";
}

}  // namespace

/// Contacts of every frame as ragged arrays: frame t owns rows offset[t] .. offset[t] + count[t].
struct ContactSeries {
  Hid group;
  Series offset, count, particleA, particleB, plane, point, normal, depth;

  ContactSeries() = default;
  ContactSeries(Io& io, hid_t file) {
    group = ::volpar::group(file, "contacts");
    offset = Series(io, group.get(), "offset", H5T_STD_I64LE, {});
    count = Series(io, group.get(), "count", H5T_STD_I64LE, {});
    particleA = Series(io, group.get(), "particle_a", H5T_STD_I32LE, {});
    particleB = Series(io, group.get(), "particle_b", H5T_STD_I32LE, {});
    plane = Series(io, group.get(), "plane", H5T_STD_I32LE, {});
    point = Series(io, group.get(), "point", H5T_IEEE_F64LE, {3});
    normal = Series(io, group.get(), "normal", H5T_IEEE_F64LE, {3});
    depth = Series(io, group.get(), "depth", H5T_IEEE_F64LE, {});
    attrString(point.id(), "unit", "m");
    attrString(depth.id(), "unit", "m");
  }
};

/// Contact patches of every frame (the narrow phase's PatchSet) as ragged arrays, like ContactSeries.
struct PatchSeries {
  Hid group;
  Series offset, count, bodyA, bodyB, plane, planeCase, source, point, normal, depth, validated, lookAhead, lookAheadCase,
      contacts;

  PatchSeries() = default;
  PatchSeries(Io& io, hid_t file) {
    group = ::volpar::group(file, "patches");
    offset = Series(io, group.get(), "offset", H5T_STD_I64LE, {});
    count = Series(io, group.get(), "count", H5T_STD_I64LE, {});
    bodyA = Series(io, group.get(), "body_a", H5T_STD_I32LE, {});
    bodyB = Series(io, group.get(), "body_b", H5T_STD_I32LE, {});
    plane = Series(io, group.get(), "plane", H5T_STD_I32LE, {});
    planeCase = Series(io, group.get(), "case", H5T_STD_I32LE, {});
    source = Series(io, group.get(), "source", H5T_STD_I32LE, {});
    point = Series(io, group.get(), "point", H5T_IEEE_F64LE, {3});
    normal = Series(io, group.get(), "normal", H5T_IEEE_F64LE, {3});
    depth = Series(io, group.get(), "depth", H5T_IEEE_F64LE, {});
    validated = Series(io, group.get(), "validated", H5T_STD_I8LE, {});
    lookAhead = Series(io, group.get(), "look_ahead", H5T_STD_I8LE, {});
    lookAheadCase = Series(io, group.get(), "look_ahead_case", H5T_STD_I32LE, {});
    contacts = Series(io, group.get(), "contacts", H5T_STD_I32LE, {});
    attrString(point.id(), "unit", "m");
    attrString(depth.id(), "unit", "m");
    std::vector<std::string> names;
    for (std::size_t k = 0; k < kPlaneCaseCount; ++k) names.emplace_back(planeCaseName(static_cast<PlaneCase>(k)));
    attrStrings(planeCase.id(), "case_names", names);
    attrStrings(lookAheadCase.id(), "case_names", names);
    names.clear();
    for (std::size_t k = 0; k < kNormalSourceCount; ++k)
      names.emplace_back(normalSourceName(static_cast<NormalSource>(k)));
    attrStrings(source.id(), "source_names", names);
  }
};

/// Per-body data that does not change over a body's life, one row per body, appended as bodies appear.
struct BodyInfoSeries {
  static constexpr std::size_t kKindWidth = 10;  ///< "deformable"
  Series name, kind, mass, moments, axes, com, created, retired, parent, gluedInto;
  std::size_t nameWidth = 1;
  BodyInfoSeries() = default;
  /// Names of up to `nameWidth` bytes.
  BodyInfoSeries(Io& io, hid_t g, std::size_t width) : nameWidth(width) {
    name = Series(io, g, "name", fixedString(nameWidth).get(), {});
    kind = Series(io, g, "kind", fixedString(kKindWidth).get(), {});
    mass = Series(io, g, "mass", H5T_IEEE_F64LE, {});
    moments = Series(io, g, "principal_moments", H5T_IEEE_F64LE, {3});
    axes = Series(io, g, "principal_axes", H5T_IEEE_F64LE, {4});
    com = Series(io, g, "com_in_shape", H5T_IEEE_F64LE, {3});
    created = Series(io, g, "created", H5T_STD_I64LE, {});
    retired = Series(io, g, "retired", H5T_STD_I64LE, {});
    parent = Series(io, g, "parent", H5T_STD_I32LE, {});
    gluedInto = Series(io, g, "glued_into", H5T_STD_I32LE, {});
    attrString(mass.id(), "unit", "kg");
    attrString(moments.id(), "unit", "kg m2");
    attrString(com.id(), "unit", "m");
  }
};

/// A connector's kind as the trajectory stores it: 0 rod, 1 spring, 2 bond.
std::int32_t kindCode(ConnectorKind k) { return k == ConnectorKind::Rod ? 0 : k == ConnectorKind::Spring ? 1 : 2; }

/// The connectors that broke, one row per event.
struct BreakageSeries {
  Hid group;
  Series step, time, connector, particleA, particleB, body, kind, value, mode, energy;
  BreakageSeries() = default;
  BreakageSeries(Io& io, hid_t file) {
    group = ::volpar::group(file, "breakage");
    step = Series(io, group.get(), "step", H5T_STD_I64LE, {});
    time = Series(io, group.get(), "time", H5T_IEEE_F64LE, {});
    connector = Series(io, group.get(), "connector", H5T_STD_I32LE, {});
    particleA = Series(io, group.get(), "particle_a", H5T_STD_I32LE, {});
    particleB = Series(io, group.get(), "particle_b", H5T_STD_I32LE, {});
    body = Series(io, group.get(), "body", H5T_STD_I32LE, {});
    kind = Series(io, group.get(), "kind", H5T_STD_I32LE, {});
    value = Series(io, group.get(), "value", H5T_IEEE_F64LE, {});
    mode = Series(io, group.get(), "mode", H5T_STD_I32LE, {});
    energy = Series(io, group.get(), "energy", H5T_IEEE_F64LE, {});
    attrString(time.id(), "unit", "s");
    attrString(energy.id(), "unit", "J");
    attrString(kind.id(), "meaning", "0: rod (value: force, N), 1: spring (value: strain), 2: bond (value: the stress that broke it, Pa)");
    attrString(mode.id(), "meaning", "0: tension, 1: compression, 2: shear, 3: strain");
  }
};

struct H5mdWriter::Impl {
  Io io;  // (first: every Series points at it)
  Hid file;
  Hid framesComplete;  // /parameters@frames_complete: the frames whose every record is on disk
  Element position, velocity, particleBody;
  Element bodyPosition, bodyOrientation, bodyVelocity, bodyAngularVelocity;
  Element kinetic, potential, total, linearMomentum, angularMomentum, contactCount, maxPenetration;
  Element patchCount, patchesByCase, unvalidatedPatches, lookAheads, candidates;
  Element fragmentCount, fragmentSizes, fragmentMass, breakageEnergy;
  ContactSeries contacts;
  PatchSeries patches;
  BodyInfoSeries bodyInfo;
  BreakageSeries breakage;
  Series connectorLines, connectorLinesOffset;
  bool linesChanged = true;            // connectors broke since /connectors/lines was last written
  std::int64_t linesOffset = 0;        // the first row of the last lines written
  std::size_t bodiesWritten = 0;       // rows in bodyInfo
  std::vector<std::uint8_t> retiredWritten;
  // scratch, reused
  std::vector<std::int32_t> bodyIndex, lineRows;
  std::vector<double> bodyVec3, bodyQuat;
  std::vector<std::int32_t> contactA, contactB, contactPlane;
  std::vector<double> contactPoint, contactNormal, contactDepth;
  std::vector<std::int32_t> patchA, patchB, patchPlane, patchCase, patchSource, patchLookAheadCase, patchContacts;
  std::vector<double> patchPoint, patchNormal, patchDepth;
  std::vector<std::int8_t> patchValidated, patchLookAhead;

  /// Rows for bodies created since the last call; the retirement of bodies that broke apart.
  void syncBodies(const BodyStore& b) {
    const std::size_t nb = b.size();
    for (std::size_t i = bodiesWritten; i < nb; ++i) {
      const BodyInfo& info = b.info[i];
      const std::string nm = padded({info.name}, bodyInfo.nameWidth, "body name");
      const std::string kd = padded({kindName(info.kind)}, BodyInfoSeries::kKindWidth, "body kind");
      bodyInfo.name.append(fixedString(bodyInfo.nameWidth).get(), nm.data());
      bodyInfo.kind.append(fixedString(BodyInfoSeries::kKindWidth).get(), kd.data());
      bodyInfo.mass.append(H5T_NATIVE_DOUBLE, &info.mass);
      bodyInfo.moments.append(H5T_NATIVE_DOUBLE, info.inertiaLocal.data());
      const Quat& q = info.principalInShape;
      const double axes[4] = {q.w(), q.x(), q.y(), q.z()};
      bodyInfo.axes.append(H5T_NATIVE_DOUBLE, axes);
      bodyInfo.com.append(H5T_NATIVE_DOUBLE, info.comInShape.data());
      bodyInfo.created.append(H5T_NATIVE_INT64, &info.createdStep);
      bodyInfo.retired.append(H5T_NATIVE_INT64, &info.retiredStep);
      const std::int32_t parent = info.parent.valid() ? static_cast<std::int32_t>(info.parent.value) : -1;
      bodyInfo.parent.append(H5T_NATIVE_INT32, &parent);
      const std::int32_t glued = info.gluedInto.valid() ? static_cast<std::int32_t>(info.gluedInto.value) : -1;
      bodyInfo.gluedInto.append(H5T_NATIVE_INT32, &glued);
      retiredWritten.push_back(info.retiredStep >= 0 ? 1 : 0);
    }
    if (nb > bodiesWritten) {
      for (Element* e : {&bodyPosition, &bodyOrientation, &bodyVelocity, &bodyAngularVelocity}) e->growTail(nb);
      bodiesWritten = nb;
      bodyVec3.resize(3 * nb);
      bodyQuat.resize(4 * nb);
    }
    for (std::size_t i = 0; i < nb; ++i)
      if (!retiredWritten[i] && b.info[i].retiredStep >= 0) {
        bodyInfo.retired.writeAt(i, H5T_NATIVE_INT64, &b.info[i].retiredStep);
        const std::int32_t glued = b.info[i].gluedInto.valid() ? static_cast<std::int32_t>(b.info[i].gluedInto.value) : -1;
        bodyInfo.gluedInto.writeAt(i, H5T_NATIVE_INT32, &glued);
        retiredWritten[i] = 1;
      }
  }
};

H5mdWriter::H5mdWriter(std::unique_ptr<Impl> impl, std::string path, std::size_t particles)
    : impl_(std::move(impl)), path_(std::move(path)), particles_(particles) {}

H5mdWriter::~H5mdWriter() { static_cast<void>(close()); }

namespace {
void makeCheckpointGroup(hid_t file);
}  // namespace

Result<std::unique_ptr<H5mdWriter>> H5mdWriter::create(const std::string& path, const World& world,
                                                       const TrajectoryMeta& meta, const FileProcesses* processes) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // errors are reported through Result, not printed by HDF5
  auto impl = std::make_unique<Impl>();
  Io& io = impl->io;
  const bool together = processes && processes->size() > 1;
  const bool lead = !together || processes->rank() == 0;  // (creates the file under its own name)
  if (together) {
    io.rank = processes->rank();
    io.size = processes->size();
  }
  const std::string creating = path + ".creating";
  try {
    // The metadata cache holds a fixed 256 KiB (serialized; about 3 MiB in memory): by default it grows with
    // the chunk indices of ~80 growing datasets up to 32 MiB, and a long run's memory climbed with it. At this
    // size it is full after about 200 frames and memory stays flat (docs/hardening.md, Soak); writing is no
    // slower (each frame touches the last index nodes of each dataset only).
    Hid fapl = checked(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, "file access property list");
    H5AC_cache_config_t mdc{};
    mdc.version = H5AC__CURR_CACHE_CONFIG_VERSION;
    check(H5Pget_mdc_config(fapl.get(), &mdc), "metadata cache settings");
    mdc.set_initial_size = true;
    mdc.initial_size = std::size_t{256} << 10;
    mdc.max_size = std::size_t{256} << 10;
    mdc.min_size = std::size_t{256} << 10;
    mdc.incr_mode = H5C_incr__off;
    mdc.flash_incr_mode = H5C_flash_incr__off;
    mdc.decr_mode = H5C_decr__off;
    check(H5Pset_mdc_config(fapl.get(), &mdc), "metadata cache settings");
    // No aggregators: HDF5 takes space for metadata and small raw data in blocks at the file's end, and gives
    // back what it did not use at each flush, moving the file's end down; it cuts the file shorter before it
    // rewrites the superblock that records the end, and a run killed in between left a file shorter than its
    // superblock says, which no longer opens. Without them the end only moves up while a run writes.
    check(H5Pset_meta_block_size(fapl.get(), 0), "metadata block size");
    check(H5Pset_small_data_block_size(fapl.get(), 0), "small data block size");
    // The 1.10 file format: a dataset whose frames are its only unlimited dimension has its chunks indexed in
    // an extensible array, and appending a frame writes new entries without moving the old ones. The original
    // format's B-tree index splits its nodes as it grows, rewriting the nodes that point at frames already
    // counted complete, and a run killed during a split left a file that no longer read (docs/hardening.md).
    // Files in this format are read by HDF5 1.10 and later (h5py, ParaView, h5dump). The file is created in
    // the original format first: the 1.10 superblock would mark the file open for writing, and HDF5 refuses to
    // open a file so marked, which is exactly what a killed run leaves behind.
    // The file is made under a temporary name and takes its own only once its structure is on disk: a run
    // killed while creating it leaves no file of that name that HDF5 could not open.
    // Several processes create the file together and write every dataset in collective calls, each its share.
    if (together) {
      if (!processes->useMpiIo(fapl.get()))
        throw H5Failure{"this HDF5 cannot write one file from several processes (it was built without parallel support)"};
      io.transfer = checked(H5Pcreate(H5P_DATASET_XFER), H5Pclose, "transfer property list");
#ifdef H5_HAVE_PARALLEL
      check(H5Pset_dxpl_mpio(io.transfer.get(), H5FD_MPIO_COLLECTIVE), "collective transfers");
#endif
    }
    impl->file = checked(H5Fcreate(creating.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), H5Fclose, "create file");
    const hid_t f = impl->file.get();
    check(H5Fset_libver_bounds(f, H5F_LIBVER_V110, H5F_LIBVER_V110), "file format version");
    const ParticleStore& p = world.particles();
    const BodyStore& b = world.bodies();
    const hsize_t np = p.size();
    const hsize_t nb = b.size();

    // /h5md
    {
      Hid h5md = group(f, "h5md");
      attrArray<std::int32_t>(h5md.get(), "version", {1, 1});
      Hid author = group(h5md.get(), "author");
      const char* user = std::getenv("USER");
      attrString(author.get(), "name", user && *user ? user : "unknown");
      Hid creator = group(h5md.get(), "creator");
      attrString(creator.get(), "name", kName);
      attrString(creator.get(), "version", kVersion);
    }
    // /particles/all
    {
      Hid all = group(f, "particles/all");
      writeBox(all.get());
      dataset<double>(io, all.get(), "radius", {np}, p.radius.data(), "m");
      dataset<double>(io, all.get(), "mass", {np}, p.mass.data(), "kg");
      impl->position = Element(io, all.get(), "position", H5T_IEEE_F64LE, {np, 3}, "m");
      impl->velocity = Element(io, all.get(), "velocity", H5T_IEEE_F64LE, {np, 3}, "m s-1", &impl->position);
      impl->particleBody = Element(io, all.get(), "body", H5T_STD_I32LE, {np}, "", &impl->position);
    }
    // /particles/bodies: one row per body ever created (bodies appear when others break apart)
    {
      Hid bodies = group(f, "particles/bodies");
      writeBox(bodies.get());
      // Breaking apart only ever splits a body into two or more, each with particles of its own, so a body of
      // n particles leaves at most 2n - 1 bodies in all: nb + 2 np bounds the bodies of any run.
      const hsize_t maxBodies = std::max<hsize_t>(nb + 2 * np, 1);
      // a fragment is named after the first part of its body's name, a slash and its index (World's breakage):
      // names are kept in as many bytes as the longest name or fragment's name could take, the same for a run
      // resumed with fragments already made (the first parts are the scene's)
      constexpr std::size_t kIndexDigits = 10;  // (a 32-bit index)
      std::size_t nameWidth = 1;
      for (std::size_t i = 0; i < nb; ++i) {
        const std::string& name = b.info[i].name;
        nameWidth = std::max({nameWidth, name.size(), name.substr(0, name.find('/')).size() + 1 + kIndexDigits});
      }
      impl->bodyInfo = BodyInfoSeries(io, bodies.get(), nameWidth);
      impl->bodyPosition = Element(io, bodies.get(), "position", H5T_IEEE_F64LE, {nb, 3}, "m", nullptr, maxBodies);
      impl->bodyOrientation =
          Element(io, bodies.get(), "orientation", H5T_IEEE_F64LE, {nb, 4}, "", &impl->bodyPosition, maxBodies);
      impl->bodyVelocity =
          Element(io, bodies.get(), "velocity", H5T_IEEE_F64LE, {nb, 3}, "m s-1", &impl->bodyPosition, maxBodies);
      impl->bodyAngularVelocity =
          Element(io, bodies.get(), "angular_velocity", H5T_IEEE_F64LE, {nb, 3}, "s-1", &impl->bodyPosition, maxBodies);
      impl->syncBodies(b);
    }
    // /breakage: every connector that broke (the engine's own group)
    impl->breakage = BreakageSeries(io, f);
    // /connectors: every connector's particles and kind, for drawing them (the engine's own group); with
    // /breakage they give the connectors standing in any frame
    {
      const ConnectorStore& c = world.connectors();
      const hsize_t nc = c.size();
      std::vector<std::int32_t> pa(nc), pb(nc), kind(nc);
      std::vector<std::int8_t> broken(nc);
      for (std::size_t i = 0; i < nc; ++i) {
        pa[i] = static_cast<std::int32_t>(c.a[i].value);
        pb[i] = static_cast<std::int32_t>(c.b[i].value);
        kind[i] = kindCode(c.kind[i]);
        broken[i] = static_cast<std::int8_t>(c.broken[i] ? 1 : 0);
      }
      Hid g = group(f, "connectors");
      dataset(io, g.get(), "particle_a", {nc}, pa.data());
      dataset(io, g.get(), "particle_b", {nc}, pb.data());
      dataset(io, g.get(), "kind", {nc}, kind.data());
      dataset(io, g.get(), "broken_before", {nc}, broken.data());
      Hid k = checked(H5Dopen2(g.get(), "kind", H5P_DEFAULT), H5Dclose, "dataset kind");
      attrString(k.get(), "meaning", "0: rod, 1: spring, 2: bond");
      // the connectors of the frames, for drawing: C rows (particle_a, particle_b; a broken connector from
      // particle_a to itself) written again only in frames after a break; lines_offset: the frame's first row
      impl->connectorLines = Series(io, g.get(), "lines", H5T_STD_I32LE, {2});
      impl->connectorLinesOffset = Series(io, g.get(), "lines_offset", H5T_STD_I64LE, {});
      impl->lineRows.resize(2 * nc);
    }
    // /observables
    {
      Hid obs = group(f, "observables");
      impl->kinetic = Element(io, obs.get(), "kinetic_energy", H5T_IEEE_F64LE, {}, "J");
      const Element* clock = &impl->kinetic;
      impl->potential = Element(io, obs.get(), "potential_energy", H5T_IEEE_F64LE, {}, "J", clock);
      impl->total = Element(io, obs.get(), "total_energy", H5T_IEEE_F64LE, {}, "J", clock);
      impl->linearMomentum = Element(io, obs.get(), "linear_momentum", H5T_IEEE_F64LE, {3}, "kg m s-1", clock);
      impl->angularMomentum = Element(io, obs.get(), "angular_momentum", H5T_IEEE_F64LE, {3}, "kg m2 s-1", clock);
      impl->contactCount = Element(io, obs.get(), "contact_count", H5T_STD_I64LE, {}, "", clock);
      impl->maxPenetration = Element(io, obs.get(), "max_penetration", H5T_IEEE_F64LE, {}, "m", clock);
      impl->patchCount = Element(io, obs.get(), "patch_count", H5T_STD_I64LE, {}, "", clock);
      impl->patchesByCase = Element(io, obs.get(), "patches_by_case", H5T_STD_I64LE, {kPlaneCaseCount}, "", clock);
      {
        std::vector<std::string> names;
        for (std::size_t k = 0; k < kPlaneCaseCount; ++k) names.push_back(planeCaseName(static_cast<PlaneCase>(k)));
        Hid g = checked(H5Gopen2(obs.get(), "patches_by_case", H5P_DEFAULT), H5Gclose, "group");
        stringDataset(io, g.get(), "case_names", names);
      }
      impl->unvalidatedPatches = Element(io, obs.get(), "unvalidated_patches", H5T_STD_I64LE, {}, "", clock);
      impl->lookAheads = Element(io, obs.get(), "look_aheads", H5T_STD_I64LE, {}, "", clock);
      impl->candidates = Element(io, obs.get(), "candidates", H5T_STD_I64LE, {}, "", clock);
      constexpr std::size_t bins = FragmentHistogram::kBins;
      impl->fragmentCount = Element(io, obs.get(), "fragment_count", H5T_STD_I64LE, {}, "", clock);
      impl->fragmentSizes = Element(io, obs.get(), "fragment_sizes", H5T_STD_I64LE, {bins}, "", clock);
      impl->fragmentMass = Element(io, obs.get(), "fragment_mass", H5T_IEEE_F64LE, {bins}, "kg", clock);
      impl->breakageEnergy = Element(io, obs.get(), "breakage_energy", H5T_IEEE_F64LE, {}, "J", clock);
      {
        // bin k: fragments of 2^k to 2^(k+1) - 1 particles
        std::vector<std::int64_t> lower(bins);
        for (std::size_t k = 0; k < bins; ++k) lower[k] = std::int64_t{1} << k;
        for (const char* name : {"fragment_sizes", "fragment_mass"}) {
          Hid g = checked(H5Gopen2(obs.get(), name, H5P_DEFAULT), H5Gclose, "group");
          dataset(io, g.get(), "bin_lower", {bins}, lower.data());
        }
      }
    }
    // /contacts (the engine's own group): ragged per-frame arrays, on the particles' clock
    impl->contacts = ContactSeries(io, f);
    check(H5Lcreate_hard(f, "particles/all/position/step", impl->contacts.group.get(), "step", H5P_DEFAULT, H5P_DEFAULT),
          "link step");
    check(H5Lcreate_hard(f, "particles/all/position/time", impl->contacts.group.get(), "time", H5P_DEFAULT, H5P_DEFAULT),
          "link time");
    // /patches (the engine's own group): the frame's contact patches, ragged like /contacts
    impl->patches = PatchSeries(io, f);
    check(H5Lcreate_hard(f, "particles/all/position/step", impl->patches.group.get(), "step", H5P_DEFAULT, H5P_DEFAULT),
          "link step");
    check(H5Lcreate_hard(f, "particles/all/position/time", impl->patches.group.get(), "time", H5P_DEFAULT, H5P_DEFAULT),
          "link time");
    // /parameters
    {
      if (meta.checkpoints) makeCheckpointGroup(f);
      Hid par = group(f, "parameters");
      scalarString(io, par.get(), "scene", meta.sceneText);
      attrString(par.get(), "scene_name", meta.sceneName);
      attrString(par.get(), "scene_file", meta.sceneFile);
      attrString(par.get(), "engine", kName);
      attrString(par.get(), "engine_version", kVersion);
      const WorldSettings& s = world.settings();
      attrScalar<double>(par.get(), "dt", s.dt);
      attrArray<double>(par.get(), "gravity", {s.gravity.x(), s.gravity.y(), s.gravity.z()});
      attrScalar<std::int32_t>(par.get(), "solver_iterations", s.solverIterations);
      attrScalar<std::int32_t>(par.get(), "substeps", s.substeps);
      attrScalar<std::int32_t>(par.get(), "output_every", meta.outputEvery);
      attrScalar<std::int64_t>(par.get(), "steps_requested", meta.stepsRequested);
      attrScalar<std::int64_t>(par.get(), "seed", static_cast<std::int64_t>(world.settings().seed));
      attrScalar<std::int64_t>(par.get(), "frames_complete", 0);
      impl->framesComplete = checked(H5Aopen(par.get(), "frames_complete", H5P_DEFAULT), H5Aclose, "attribute frames_complete");
      // planes: normal (3) and offset per row
      std::vector<double> planes;
      for (const Plane& pl : world.planes()) planes.insert(planes.end(), {pl.normal.x(), pl.normal.y(), pl.normal.z(), pl.offset});
      dataset<double>(io, par.get(), "planes", {world.planes().size(), 4}, planes.data(), "");
      if (!meta.extraFiles.empty()) {
        Hid files = group(par.get(), "files");
        std::set<std::string> used;
        for (const std::string& file : meta.extraFiles) {
          std::string name = std::filesystem::path(file).filename().string();
          if (name.empty() || name[0] == '.') name = "file" + name;
          for (int k = 2; used.contains(name); ++k) name = std::filesystem::path(file).filename().string() + "_" + std::to_string(k);
          used.insert(name);
          auto text = readInputFile(file, kMaxMeshFileBytes, "mesh file");
          if (!text) throw H5Failure{"cannot store " + text.error().toString()};
          scalarString(io, files.get(), name, *text);
        }
      }
    }
    impl->bodyIndex.resize(p.size());
    check(H5Fflush(f, H5F_SCOPE_GLOBAL), "flush");
    std::error_code ec;
    if (lead) std::filesystem::rename(creating, path, ec);  // (HDF5 goes on writing through its open descriptor)
    if (together && processes->any(static_cast<bool>(ec)) && !ec) throw H5Failure{"process 0 could not rename " + creating};
    if (ec) throw H5Failure{"rename " + creating + ": " + ec.message()};
  } catch (const H5Failure& e) {
    // (with several processes, closing is collective and the others may be elsewhere: the failure ends them all,
    // and the handles are left to the end of the process)
    if (together) static_cast<void>(impl.release());
    impl.reset();
    std::error_code ignored;
    if (lead) std::filesystem::remove(creating, ignored);
    return Error{path, 0, 0, "cannot write trajectory (" + e.what + ")"};
  }
  auto writer = std::unique_ptr<H5mdWriter>(new H5mdWriter(std::move(impl), path, world.particles().size()));
  writer->processes_ = together ? processes : nullptr;
  // what the sidecar draws besides the particles
  writer->connectors_ = world.connectors().size();
  for (const Plane& pl : world.planes()) writer->planes_.push_back({pl.normal.x(), pl.normal.y(), pl.normal.z(), pl.offset});
  return writer;
}

Status H5mdWriter::writeFrame(const World& world) {
  if (!impl_ || !impl_->file.valid()) return Error{path_, 0, 0, "trajectory is closed"};
  const std::int64_t step = world.stepIndex();
  const double time = world.time();
  const ParticleStore& p = world.particles();
  const BodyStore& b = world.bodies();
  Impl& m = *impl_;
  // A write that fails part way can leave HDF5's record of the file's end past its real end, and such a file
  // no longer opens: a frame is begun only with room on the disk for twice the most a commit has added so far
  // (the frames a commit writes out may sit in HDF5's caches until then), plus room to close the file.
  std::uint64_t sizeBefore = 0;
  if (!fileSize(sizeBefore)) return Error{path_, 0, 0, "cannot read the trajectory's size"};
  constexpr std::uint64_t kCloseRoom = std::uint64_t{1} << 20;
  const std::uint64_t needed = 2 * largestCommit_ + kCloseRoom;
  const std::uint64_t room = roomToGrow(path_, sizeBefore);
  if ((failedTogether_ = agree(room < needed)))
    return Error{path_, 0, 0, (room < needed ? "not enough room: the disk or the file-size limit leaves " + std::to_string(room) +
                                                   " more bytes and a frame may need " + std::to_string(needed)
                                             : std::string("not enough room for another process")) +
                                  "; stopped before frame " + std::to_string(times_.size())};
  try {
    m.position.append(H5T_NATIVE_DOUBLE, p.position.data()->data(), step, time);
    m.velocity.append(H5T_NATIVE_DOUBLE, p.velocity.data()->data(), step, time);
    for (std::size_t i = 0; i < p.size(); ++i) m.bodyIndex[i] = static_cast<std::int32_t>(p.body[i].value);
    m.particleBody.append(H5T_NATIVE_INT32, m.bodyIndex.data(), step, time);

    m.syncBodies(b);
    const std::size_t nb = b.size();
    constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
    // a body that broke apart has no state any more: NaN from its retirement on
    auto vec3s = [&](auto get) {
      for (std::size_t i = 0; i < nb; ++i)
        for (int k = 0; k < 3; ++k) m.bodyVec3[3 * i + static_cast<std::size_t>(k)] = b.info[i].alive ? get(i)[k] : kNan;
      return m.bodyVec3.data();
    };
    m.bodyPosition.append(H5T_NATIVE_DOUBLE, vec3s([&](std::size_t i) { return b.state[i].position; }), step, time);
    for (std::size_t i = 0; i < nb; ++i) {
      const Quat q = b.shapeOrientation(BodyId(i));
      const bool alive = b.info[i].alive;
      m.bodyQuat[4 * i + 0] = alive ? q.w() : kNan;
      m.bodyQuat[4 * i + 1] = alive ? q.x() : kNan;
      m.bodyQuat[4 * i + 2] = alive ? q.y() : kNan;
      m.bodyQuat[4 * i + 3] = alive ? q.z() : kNan;
    }
    m.bodyOrientation.append(H5T_NATIVE_DOUBLE, m.bodyQuat.data(), step, time);
    m.bodyVelocity.append(H5T_NATIVE_DOUBLE, vec3s([&](std::size_t i) { return b.state[i].linearVelocity; }), step, time);
    m.bodyAngularVelocity.append(H5T_NATIVE_DOUBLE, vec3s([&](std::size_t i) { return b.state[i].angularVelocity; }),
                                 step, time);

    const EnergyReport e = world.energy();
    const double kinetic = e.kinetic, potential = e.potential, total = e.total();
    m.kinetic.append(H5T_NATIVE_DOUBLE, &kinetic, step, time);
    m.potential.append(H5T_NATIVE_DOUBLE, &potential, step, time);
    m.total.append(H5T_NATIVE_DOUBLE, &total, step, time);
    const Vec3 lin = world.linearMomentum();
    const Vec3 ang = world.angularMomentum();
    m.linearMomentum.append(H5T_NATIVE_DOUBLE, lin.data(), step, time);
    m.angularMomentum.append(H5T_NATIVE_DOUBLE, ang.data(), step, time);
    const std::int64_t contactCount = static_cast<std::int64_t>(world.stats().contacts);
    const double deepest = world.stats().maxPenetration;
    m.contactCount.append(H5T_NATIVE_INT64, &contactCount, step, time);
    m.maxPenetration.append(H5T_NATIVE_DOUBLE, &deepest, step, time);
    const StepStats& st = world.stats();
    const auto asInt = [](std::size_t v) { return static_cast<std::int64_t>(v); };
    const std::int64_t patches = asInt(st.patches), unvalidated = asInt(st.unvalidatedPatches),
                       lookAheads = asInt(st.lookAheads), candidates = asInt(st.candidates);
    std::array<std::int64_t, kPlaneCaseCount> byCase{};
    for (std::size_t k = 0; k < kPlaneCaseCount; ++k) byCase[k] = asInt(st.patchesByCase[k]);
    m.patchCount.append(H5T_NATIVE_INT64, &patches, step, time);
    m.patchesByCase.append(H5T_NATIVE_INT64, byCase.data(), step, time);
    m.unvalidatedPatches.append(H5T_NATIVE_INT64, &unvalidated, step, time);
    m.lookAheads.append(H5T_NATIVE_INT64, &lookAheads, step, time);
    m.candidates.append(H5T_NATIVE_INT64, &candidates, step, time);
    const FragmentHistogram fragments = world.fragments();
    const std::int64_t fragmentCount = asInt(fragments.count);
    const double breakageEnergy = world.breakageEnergy();
    m.fragmentCount.append(H5T_NATIVE_INT64, &fragmentCount, step, time);
    m.fragmentSizes.append(H5T_NATIVE_INT64, fragments.bodies.data(), step, time);
    m.fragmentMass.append(H5T_NATIVE_DOUBLE, fragments.mass.data(), step, time);
    m.breakageEnergy.append(H5T_NATIVE_DOUBLE, &breakageEnergy, step, time);
    writeContacts(world.contacts());
    writePatches(world.patches());
    const ConnectorStore& c = world.connectors();
    if (m.linesChanged && c.size() > 0) {
      for (std::size_t i = 0; i < c.size(); ++i) {
        m.lineRows[2 * i] = static_cast<std::int32_t>(c.a[i].value);
        m.lineRows[2 * i + 1] = static_cast<std::int32_t>(c.broken[i] ? c.a[i].value : c.b[i].value);
      }
      m.linesOffset = static_cast<std::int64_t>(m.connectorLines.rows());
      m.connectorLines.appendRows(H5T_NATIVE_INT32, m.lineRows.data(), c.size());
    }
    m.linesChanged = false;
    m.connectorLinesOffset.append(H5T_NATIVE_INT64, &m.linesOffset);
  } catch (const H5Failure& e) {
    return Error{path_, 0, 0, "cannot write frame " + std::to_string(times_.size()) + " (" + e.what + "); the file holds " +
                                  std::to_string(committed_) + " complete frames"};
  }
  bounds_.add(p.position);
  times_.push_back(time);
  steps_.push_back(step);
  const auto patches = static_cast<std::int64_t>(world.patches().patches.size());
  patchOffsets_.push_back(static_cast<std::int64_t>(m.patches.bodyA.rows()) - patches);
  patchCounts_.push_back(patches);
  linesOffsets_.push_back(m.linesOffset);
  // (the first frame at once: a file that opens holds at least the state the run started from)
  // (processes writing together commit together, when any one's interval has passed)
  if (commitSeconds_ <= 0.0 || committed_ == 0 ||
      agree(std::chrono::duration<double>(std::chrono::steady_clock::now() - lastCommit_).count() >= commitSeconds_))
    return commit();
  return okStatus();
}

Status H5mdWriter::commit() {
  if (!impl_ || !impl_->file.valid()) return Error{path_, 0, 0, "trajectory is closed"};
  Impl& m = *impl_;
  lastCommit_ = std::chrono::steady_clock::now();
  if (committed_ == times_.size()) return okStatus();
  try {
    // All or nothing: the frames' records reach the disk first, then the count that includes them, so a
    // kill or a full disk at any point leaves a count of frames that are all complete (docs/hardening.md).
    check(H5Fflush(m.file.get(), H5F_SCOPE_GLOBAL), "flush");
    const auto complete = static_cast<std::int64_t>(times_.size());
    check(H5Awrite(m.framesComplete.get(), H5T_NATIVE_INT64, &complete), "attribute frames_complete");
    check(H5Fflush(m.file.get(), H5F_SCOPE_GLOBAL), "flush");
  } catch (const H5Failure& e) {
    return Error{path_, 0, 0, "cannot write frames " + std::to_string(committed_) + " to " + std::to_string(times_.size() - 1) +
                                  " (" + e.what + "); the file holds " + std::to_string(committed_) + " complete frames"};
  }
  committed_ = times_.size();
  std::uint64_t size = 0;
  if (fileSize(size)) {
    if (size > sizeAtCommit_) largestCommit_ = std::max<std::uint64_t>(largestCommit_, size - sizeAtCommit_);
    sizeAtCommit_ = size;
  }
  return okStatus();
}

void H5mdWriter::writeContacts(const ContactSet& set) {
  Impl& m = *impl_;
  // touching contacts only (speculative ones are the solver's business)
  std::size_t n = 0;
  for (const ParticleContact& c : set.contacts) n += c.touching() ? 1 : 0;
  m.contactA.resize(n);
  m.contactB.resize(n);
  m.contactPlane.resize(n);
  m.contactPoint.resize(3 * n);
  m.contactNormal.resize(3 * n);
  m.contactDepth.resize(n);
  std::size_t i = 0;
  for (const ParticleContact& c : set.contacts) {
    if (!c.touching()) continue;
    m.contactA[i] = static_cast<std::int32_t>(c.a.value);
    m.contactB[i] = c.b.valid() ? static_cast<std::int32_t>(c.b.value) : -1;
    m.contactPlane[i] = c.plane.valid() ? static_cast<std::int32_t>(c.plane.value) : -1;
    for (int k = 0; k < 3; ++k) {
      m.contactPoint[3 * i + static_cast<std::size_t>(k)] = c.point[k];
      m.contactNormal[3 * i + static_cast<std::size_t>(k)] = c.normal[k];
    }
    m.contactDepth[i] = c.depth;
    ++i;
  }
  ContactSeries& cs = m.contacts;
  const auto offset = static_cast<std::int64_t>(cs.particleA.rows());
  const auto count = static_cast<std::int64_t>(n);
  cs.offset.append(H5T_NATIVE_INT64, &offset);
  cs.count.append(H5T_NATIVE_INT64, &count);
  cs.particleA.appendRows(H5T_NATIVE_INT32, m.contactA.data(), n);
  cs.particleB.appendRows(H5T_NATIVE_INT32, m.contactB.data(), n);
  cs.plane.appendRows(H5T_NATIVE_INT32, m.contactPlane.data(), n);
  cs.point.appendRows(H5T_NATIVE_DOUBLE, m.contactPoint.data(), n);
  cs.normal.appendRows(H5T_NATIVE_DOUBLE, m.contactNormal.data(), n);
  cs.depth.appendRows(H5T_NATIVE_DOUBLE, m.contactDepth.data(), n);
}

void H5mdWriter::writePatches(const PatchSet& set) {
  Impl& m = *impl_;
  const std::size_t n = set.patches.size();
  m.patchA.resize(n);
  m.patchB.resize(n);
  m.patchPlane.resize(n);
  m.patchCase.resize(n);
  m.patchSource.resize(n);
  m.patchContacts.resize(n);
  m.patchPoint.resize(3 * n);
  m.patchNormal.resize(3 * n);
  m.patchDepth.resize(n);
  m.patchValidated.resize(n);
  m.patchLookAhead.resize(n);
  m.patchLookAheadCase.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const ContactPatch& p = set.patches[i];
    m.patchA[i] = static_cast<std::int32_t>(p.a.value);
    m.patchB[i] = p.b.valid() ? static_cast<std::int32_t>(p.b.value) : -1;
    m.patchPlane[i] = p.plane.valid() ? static_cast<std::int32_t>(p.plane.value) : -1;
    m.patchCase[i] = static_cast<std::int32_t>(p.planeCase);
    m.patchSource[i] = static_cast<std::int32_t>(p.source);
    m.patchContacts[i] = static_cast<std::int32_t>(p.count);
    for (int k = 0; k < 3; ++k) {
      m.patchPoint[3 * i + static_cast<std::size_t>(k)] = p.point[k];
      m.patchNormal[3 * i + static_cast<std::size_t>(k)] = p.normal[k];
    }
    m.patchDepth[i] = p.depth;
    m.patchValidated[i] = p.validated ? 1 : 0;
    m.patchLookAhead[i] = p.lookAhead ? 1 : 0;
    // the case of the configuration the look-ahead predicted, -1 where none decided the plane
    m.patchLookAheadCase[i] = p.lookAhead ? static_cast<std::int32_t>(p.lookAheadCase) : -1;
  }
  PatchSeries& ps = m.patches;
  const auto offset = static_cast<std::int64_t>(ps.bodyA.rows());
  const auto count = static_cast<std::int64_t>(n);
  ps.offset.append(H5T_NATIVE_INT64, &offset);
  ps.count.append(H5T_NATIVE_INT64, &count);
  ps.bodyA.appendRows(H5T_NATIVE_INT32, m.patchA.data(), n);
  ps.bodyB.appendRows(H5T_NATIVE_INT32, m.patchB.data(), n);
  ps.plane.appendRows(H5T_NATIVE_INT32, m.patchPlane.data(), n);
  ps.planeCase.appendRows(H5T_NATIVE_INT32, m.patchCase.data(), n);
  ps.source.appendRows(H5T_NATIVE_INT32, m.patchSource.data(), n);
  ps.point.appendRows(H5T_NATIVE_DOUBLE, m.patchPoint.data(), n);
  ps.normal.appendRows(H5T_NATIVE_DOUBLE, m.patchNormal.data(), n);
  ps.depth.appendRows(H5T_NATIVE_DOUBLE, m.patchDepth.data(), n);
  ps.validated.appendRows(H5T_NATIVE_INT8, m.patchValidated.data(), n);
  ps.lookAhead.appendRows(H5T_NATIVE_INT8, m.patchLookAhead.data(), n);
  ps.lookAheadCase.appendRows(H5T_NATIVE_INT32, m.patchLookAheadCase.data(), n);
  ps.contacts.appendRows(H5T_NATIVE_INT32, m.patchContacts.data(), n);
}

Status H5mdWriter::writeBreakEvents(const World& world) {
  if (!impl_ || !impl_->file.valid()) return Error{path_, 0, 0, "trajectory is closed"};
  BreakageSeries& s = impl_->breakage;
  try {
    for (const BreakEvent& e : world.breakEvents()) {
      const double t = static_cast<double>(e.step) * world.settings().dt;
      const auto i32 = [](std::uint32_t v) { return static_cast<std::int32_t>(v); };
      const std::int32_t c = i32(e.connector.value), a = i32(e.a.value), bb = i32(e.b.value), body = i32(e.body.value),
                         kind = kindCode(e.kind),
                         mode = static_cast<std::int32_t>(e.mode);
      s.step.append(H5T_NATIVE_INT64, &e.step);
      s.time.append(H5T_NATIVE_DOUBLE, &t);
      s.connector.append(H5T_NATIVE_INT32, &c);
      s.particleA.append(H5T_NATIVE_INT32, &a);
      s.particleB.append(H5T_NATIVE_INT32, &bb);
      s.body.append(H5T_NATIVE_INT32, &body);
      s.kind.append(H5T_NATIVE_INT32, &kind);
      s.value.append(H5T_NATIVE_DOUBLE, &e.value);
      s.mode.append(H5T_NATIVE_INT32, &mode);
      s.energy.append(H5T_NATIVE_DOUBLE, &e.energy);
    }
    impl_->linesChanged = impl_->linesChanged || !world.breakEvents().empty();
  } catch (const H5Failure& e) {
    return Error{path_, 0, 0, "cannot write breakage events (" + e.what + ")"};
  }
  return okStatus();
}

namespace {

/// /checkpoint: two slot groups and the attributes that say which holds the checkpoint (step -1: none yet).
void makeCheckpointGroup(hid_t file) {
  Hid top = group(file, "checkpoint");
  attrScalar<std::int64_t>(top.get(), "step", -1);
  attrScalar<std::int64_t>(top.get(), "slot", -1);
  group(top.get(), "slot_0");
  group(top.get(), "slot_1");
}

/// Writes a scalar int64 attribute that exists already, in place (its header message keeps its size and place).
void rewriteAttr(hid_t obj, const char* name, std::int64_t value) {
  Hid attr = checked(H5Aopen(obj, name, H5P_DEFAULT), H5Aclose, std::string("attribute ") + name);
  check(H5Awrite(attr.get(), H5T_NATIVE_INT64, &value), std::string("write attribute ") + name);
}

/// The names of the links in a group.
herr_t collectLink(hid_t, const char* name, const H5L_info_t*, void* out) {
  static_cast<std::vector<std::string>*>(out)->emplace_back(name);
  return 0;
}

}  // namespace

Status H5mdWriter::writeCheckpoint(const World& world, std::int64_t endStep) {
  if (!impl_ || !impl_->file.valid()) return Error{path_, 0, 0, "trajectory is closed"};
  const std::int64_t step = world.stepIndex();
  if (step == checkpointStep_) return okStatus();
  // the frames up to the checkpoint count before it does
  if (auto ok = commit(); !ok) return ok;
  StateArchive archive;
  world.saveState(archive);
  const hid_t f = impl_->file.get();
  // as for frames: begun only with room for it twice over and for closing the file
  std::uint64_t sizeBefore = 0;
  if (!fileSize(sizeBefore)) return Error{path_, 0, 0, "cannot read the trajectory's size"};
  const std::uint64_t needed = 2 * archive.bytes() + (std::uint64_t{2} << 20);
  const std::uint64_t room = roomToGrow(path_, sizeBefore);
  if ((failedTogether_ = agree(room < needed)))
    return Error{path_, 0, 0, "not enough room for the checkpoint of step " + std::to_string(step) +
                                  (room < needed ? ": the disk or the file-size limit leaves " + std::to_string(room) +
                                                       " more bytes and it may need " + std::to_string(needed)
                                                 : std::string(" on another process"))};
  try {
    // the checkpoint goes into the slot that does not hold the current one; only that slot changes until it
    // is complete on disk, and then two attributes of /checkpoint, in place
    if (H5Lexists(f, "checkpoint", H5P_DEFAULT) <= 0) makeCheckpointGroup(f);
    Hid top = checked(H5Gopen2(f, "checkpoint", H5P_DEFAULT), H5Gclose, "group checkpoint");
    const int slot = checkpointSlot_ == 0 ? 1 : 0;
    const std::string slotName = "slot_" + std::to_string(slot);
    Hid g = checked(H5Gopen2(top.get(), slotName.c_str(), H5P_DEFAULT), H5Gclose, "group " + slotName);
    std::vector<std::string> old;
    check(H5Literate(g.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collectLink, &old), "list " + slotName);
    for (const std::string& name : old) check(H5Ldelete(g.get(), name.c_str(), H5P_DEFAULT), "drop " + name);
    for (const char* name : {"step", "time", "frames", "end_step"})
      if (H5Aexists(g.get(), name) > 0) check(H5Adelete(g.get(), name), std::string("drop attribute ") + name);
    // contiguous, uncompressed, written once: a reader can tell its size from its shape
    for (const StateArchive::Array& a : archive.arrays()) {
      if (const std::size_t slash = a.name.rfind('/'); slash != std::string::npos) {
        const std::string folder = a.name.substr(0, slash);
        if (H5Lexists(g.get(), folder.c_str(), H5P_DEFAULT) <= 0) group(g.get(), folder);
      }
      std::vector<hsize_t> dims{a.rows()};
      if (a.width > 1) dims.push_back(a.width);
      hid_t fileType = H5T_IEEE_F64LE, memType = H5T_NATIVE_DOUBLE;
      switch (a.type) {
        case StateArchive::Type::F64: break;
        case StateArchive::Type::F32: fileType = H5T_IEEE_F32LE; memType = H5T_NATIVE_FLOAT; break;
        case StateArchive::Type::I64: fileType = H5T_STD_I64LE; memType = H5T_NATIVE_INT64; break;
        case StateArchive::Type::U32: fileType = H5T_STD_U32LE; memType = H5T_NATIVE_UINT32; break;
        case StateArchive::Type::U8: fileType = H5T_STD_U8LE; memType = H5T_NATIVE_UINT8; break;
      }
      Hid space = checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose, "space");
      Hid dcpl = datasetPlist();
      Hid ds = checked(H5Dcreate2(g.get(), a.name.c_str(), fileType, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose,
                       "dataset " + a.name);
      if (!a.bytes.empty()) writeBlock(impl_->io, ds.get(), memType, std::vector<hsize_t>(dims.size(), 0), dims, {}, a.bytes.data(), a.name);
    }
    attrScalar<std::int64_t>(g.get(), "step", step);
    attrScalar<double>(g.get(), "time", world.time());
    attrScalar<std::int64_t>(g.get(), "frames", static_cast<std::int64_t>(frames()));
    attrScalar<std::int64_t>(g.get(), "end_step", endStep);
    check(H5Fflush(f, H5F_SCOPE_GLOBAL), "flush");
    // the new checkpoint is on disk: make it the file's
    rewriteAttr(top.get(), "step", step);
    rewriteAttr(top.get(), "slot", slot);
    check(H5Fflush(f, H5F_SCOPE_GLOBAL), "flush");
    checkpointSlot_ = slot;
  } catch (const H5Failure& e) {
    return Error{path_, 0, 0, "cannot write the checkpoint of step " + std::to_string(step) + " (" + e.what + ")"};
  }
  checkpointStep_ = step;
  return okStatus();
}

Status H5mdWriter::writeSidecar(const std::string& h5Path) const {
  if (processes_ && processes_->rank() != 0) return okStatus();  // (process 0's)
  // the complete frames only
  const auto n = static_cast<std::ptrdiff_t>(committed_);
  XdmfFrames f;
  f.h5Path = h5Path;
  f.particles = particles_;
  f.time.assign(times_.begin(), times_.begin() + n);
  f.step.assign(steps_.begin(), steps_.begin() + n);
  f.patchOffset.assign(patchOffsets_.begin(), patchOffsets_.begin() + n);
  f.patchCount.assign(patchCounts_.begin(), patchCounts_.begin() + n);
  f.connectors = connectors_;
  f.connectorOffset.assign(linesOffsets_.begin(), linesOffsets_.begin() + n);
  f.planes = planes_;
  f.bounds = bounds_;
  return writeXdmf(f);
}

void H5mdWriter::closeAfterFailure() {
  if (!processes_ || failedTogether_) {
    static_cast<void>(close());
    return;
  }
  if (impl_) bytesWritten_ = impl_->io.bytes;
  static_cast<void>(impl_.release());  // (closing is collective: the handles go with the process)
}

std::uint64_t H5mdWriter::bytesWritten() const { return impl_ ? impl_->io.bytes : bytesWritten_; }

bool H5mdWriter::fileSize(std::uint64_t& size) const {
  if (!processes_) {
    hsize_t bytes = 0;
    if (H5Fget_filesize(impl_->file.get(), &bytes) < 0) return false;
    size = bytes;
    return true;
  }
  // (HDF5's MPI-IO driver does not tell the size: the file system does)
  std::error_code ec;
  size = std::filesystem::file_size(path_, ec);
  return !ec;
}

bool H5mdWriter::agree(bool mine) const { return processes_ ? processes_->any(mine) : mine; }

Status H5mdWriter::close() {
  if (!impl_ || !impl_->file.valid()) return okStatus();
  if (auto ok = commit(); !ok) {
    impl_.reset();
    return ok;
  }
  const herr_t flushed = H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL);
  bytesWritten_ = impl_->io.bytes;
  const hid_t file = impl_->file.release();
  impl_.reset();  // closes every dataset and attribute
  const herr_t closed = H5Fclose(file);
  if (flushed < 0 || closed < 0) return Error{path_, 0, 0, "cannot flush and close the trajectory (disk full?)"};
  return okStatus();
}

}  // namespace volpar
