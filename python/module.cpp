// The Python module `fluoro`: the engine, the backends and the registration with NumPy arrays in
// and out (docs/python.md). InputError (bad input) becomes ValueError with the same one-line
// message; every kernel and registration call releases the GIL.
#include "engine/error.hpp"
#include "engine/version.hpp"
#include "python/common.hpp"

namespace py = pybind11;

PYBIND11_MODULE(fluoro, m) {
  m.doc() = "fluoro: DRRs, gradient fields, GPR scores and 2D/3D registration of CTs to X-rays";
  m.attr("__version__") = fluoro::kVersion;
  // BackendUnavailable is a ValueError too (bad input to the program), tests skip on it.
  static py::exception<fluoro::BackendUnavailable> unavailable(m, "BackendUnavailable", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const fluoro::BackendUnavailable& e) {
      PyErr_SetString(unavailable.ptr(), e.what());
    } catch (const fluoro::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  fluoro::py_bind::bind_core(m);
  fluoro::py_bind::bind_pipelines(m);
  fluoro::py_bind::bind_calibration(m);
  fluoro::py_bind::bind_points(m);
  fluoro::py_bind::bind_panorama(m);
}
