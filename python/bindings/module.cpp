// _fpss_stand: the native module under the fpss_stand package (python/fpss_stand/__init__.py wraps it).
#include <pybind11/pybind11.h>

#include "base/errors.h"
#include "convert.h"
#include "stand/catalogue/catalogue.h"

PYBIND11_MODULE(_fpss_stand, m) {
  namespace py = pybind11;
  m.doc() = "fpss-stand's libraries for Python (the calibrator, the diagnosis, the design, the catalogue, the run folder)";
  // Bad input: a ValueError whose message names the file, line or key. DataError (the data cannot
  // answer) is one of them. pybind11 tries the translator registered last first: DataError's.
  static py::exception<fpss::InputError> input_error(m, "InputError", PyExc_ValueError);
  static py::exception<fpss::DataError> data_error(m, "DataError", input_error.ptr());
  static py::exception<fpss::CatalogueUnavailable> unavailable(m, "CatalogueUnavailable", PyExc_ConnectionError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const fpss::InputError& e) {
      // DataError first: it is an InputError too.
      if (dynamic_cast<const fpss::DataError*>(&e)) data_error(e.what());
      else input_error(e.what());
    } catch (const fpss::CatalogueUnavailable& e) {
      unavailable(e.what());
    }
  });
  fpss::pybind::bind_samples(m);
  fpss::pybind::bind_calib(m);
  fpss::pybind::bind_catalogue(m);
  fpss::pybind::bind_run_folder(m);
}
