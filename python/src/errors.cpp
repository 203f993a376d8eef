// volpar.Error and the checks of arguments.

#include <cmath>
#include <sstream>

#include "python/src/common.hpp"

namespace volpar::python {

namespace {

PyObject* gError = nullptr;  // volpar.Error (a new reference held for the life of the interpreter)

constexpr const char* kErrorDoc =
    "Bad input or a failed run: a scene file with a syntax error, an unknown key or a value out of range, a\n"
    "missing file, an argument out of range, a trajectory that cannot be written, a simulation that became\n"
    "non-finite. A subclass of ValueError.\n"
    "\n"
    "str(error) is exactly what `volpar run` prints after 'volpar: error: ' for the same input, e.g.\n"
    "'scene.yaml:2:1: unknown key 'foo' in scene; expected one of: ...'. Arguments that `volpar run` takes as\n"
    "options are named by the option in the message ('--steps: expected a whole number from 1 to ..., got 0').\n"
    "\n"
    "Attributes:\n"
    "    file (str): the file the error is located in ('' when it is not located in a file)\n"
    "    line (int): 1-based line in that file, 0 when unknown\n"
    "    column (int): 1-based column, 0 when unknown\n"
    "    message (str): what was expected, without the location\n";

void setError(const Error& e) {
  const py::handle type(gError);
  py::object exc = type(e.toString());
  exc.attr("file") = e.file;
  exc.attr("line") = e.line;
  exc.attr("column") = e.column;
  exc.attr("message") = e.message;
  PyErr_SetObject(gError, exc.ptr());
}

}  // namespace

void bindErrors(py::module_& m) {
  gError = PyErr_NewExceptionWithDoc("volpar.Error", kErrorDoc, PyExc_ValueError, nullptr);
  if (!gError) throw py::error_already_set();
  m.add_object("Error", py::handle(gError));
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const PyError& e) {
      setError(e.error());
    }
  });
}

std::string str(py::handle value) { return py::str(value).cast<std::string>(); }

std::string repr(double v) { return str(py::float_(v)); }

std::int64_t wholeNumber(py::handle value, const std::string& name, long long lo, long long hi) {
  // as tools/volpar.cpp's wholeNumber words it for the text of an option
  const auto range = [&] {
    return name + ": expected a whole number from " + std::to_string(lo) + " to " + std::to_string(hi) + ", got " + str(value);
  };
  if (PyBool_Check(value.ptr()) || !PyIndex_Check(value.ptr())) raise(name + ": expected a whole number, got " + str(value));
  const py::object index = py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()));
  if (!index) throw py::error_already_set();
  int overflow = 0;
  const long long v = PyLong_AsLongLongAndOverflow(index.ptr(), &overflow);
  if (overflow != 0) raise(range());
  if (v == -1 && PyErr_Occurred()) throw py::error_already_set();
  if (v < lo || v > hi) raise(range());
  return v;
}

double number(py::handle value, const std::string& name) {
  if (PyBool_Check(value.ptr()) || PyUnicode_Check(value.ptr()) || PyBytes_Check(value.ptr()) ||
      !(PyFloat_Check(value.ptr()) || PyIndex_Check(value.ptr()) || py::hasattr(value, "__float__")))
    raise(name + ": expected a number, got " + str(value));
  const double v = PyFloat_AsDouble(value.ptr());
  if (v == -1.0 && PyErr_Occurred()) {
    PyErr_Clear();
    raise(name + ": expected a number, got " + str(value));
  }
  return v;
}

double positiveFinite(py::handle value, const std::string& name) {
  // as tools/volpar.cpp's positiveFinite words it
  const double v = number(value, name);
  if (!std::isfinite(v) || !(v > 0.0)) raise(name + ": expected a finite number above 0, got " + str(value));
  return v;
}

namespace {
std::string formatted(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}
}  // namespace

double positive(double v, const std::string& arg, const std::string& what, const std::string& unit) {
  if (!(v > 0.0)) raise(arg + ": expected a positive " + what + " [" + unit + "], got " + repr(v));
  if (unit == "m" && !(std::abs(v) <= kMaxLength))
    raise(arg + ": expected " + what + " of at most " + formatted(kMaxLength) + " m in magnitude, got " + repr(v));
  if (!std::isfinite(v)) raise(arg + ": expected a finite number for " + what + ", got " + repr(v));
  return v;
}

double nonNegative(double v, const std::string& arg, const std::string& what, const std::string& unit) {
  if (!(v >= 0.0)) raise(arg + ": expected a non-negative " + what + " [" + unit + "], got " + repr(v));
  if (unit == "m" && !(std::abs(v) <= kMaxLength))
    raise(arg + ": expected " + what + " of at most " + formatted(kMaxLength) + " m in magnitude, got " + repr(v));
  if (!std::isfinite(v)) raise(arg + ": expected a finite number for " + what + ", got " + repr(v));
  return v;
}

double inRange(double v, const std::string& arg, const std::string& what, double lo, double hi) {
  if (!(v >= lo && v <= hi))
    raise(arg + ": expected " + what + " in [" + formatted(lo) + ", " + formatted(hi) + "], got " + repr(v));
  return v;
}

Vec3 vec3(const std::array<double, 3>& v, const std::string& arg, const std::string& what, double limit,
          const std::string& unit) {
  for (const double c : v)
    if (!(std::abs(c) <= limit))
      raise(arg + ": expected components of " + what + " of at most " + formatted(limit) + " " + unit +
            " in magnitude, got " + repr(c));
  return Vec3(v[0], v[1], v[2]);
}

Quat quaternion(const std::array<double, 4>& wxyz, const std::string& arg) {
  Eigen::Vector4d q(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
  if (!q.allFinite()) raise(arg + ": expected a quaternion [w, x, y, z] of 4 finite numbers");
  const double largest = q.cwiseAbs().maxCoeff();
  if (!(largest > 0.0)) raise(arg + ": expected a non-zero quaternion [w, x, y, z]");
  q /= largest;  // (as the scene loader: neither overflows nor underflows)
  q.normalize();
  return Quat(q[0], q[1], q[2], q[3]);
}

Vec3 direction(const std::array<double, 3>& v, const std::string& arg, const std::string& what) {
  Vec3 d(v[0], v[1], v[2]);
  if (!d.allFinite()) raise(arg + ": expected a finite " + what);
  const double largest = d.cwiseAbs().maxCoeff();
  if (!(largest > 0.0)) raise(arg + ": expected a non-zero " + what);
  d /= largest;
  return d.normalized();
}

std::string oneOf(const std::string& value, const std::string& arg, const std::string& what,
                  const std::vector<std::string>& options) {
  for (const std::string& o : options)
    if (o == value) return value;
  std::string list;
  for (const std::string& o : options) list += (list.empty() ? "" : ", ") + o;
  raise(arg + ": unknown " + what + " '" + value + "'; expected one of: " + list);
}

}  // namespace volpar::python
