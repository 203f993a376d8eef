// The Python module volpar (the extension volpar._volpar; docs/python.md).

#include "python/src/common.hpp"
#include "volpar/engine/core/version.hpp"

PYBIND11_MODULE(_volpar, m) {
  using namespace volpar::python;
  m.doc() = "The compiled part of the volpar package (import volpar; see docs/python.md).";
  m.attr("__version__") = volpar::kVersion;
  // the classes and functions are volpar's (the package re-exports them): named so in help(), repr() and signatures
  const py::object name = m.attr("__name__");
  m.attr("__name__") = "volpar";
  bindErrors(m);
  bindBuilders(m);
  bindWorld(m);
  bindScene(m);
  bindRun(m);
  m.attr("__name__") = name;
}
