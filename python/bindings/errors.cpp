// incise's errors as Python exceptions carrying the command line's messages (file, line, key,
// element):
//   incise.Error       (RuntimeError)            anything incise refuses or fails at
//   incise.InputError  (incise.Error, ValueError) bad input: a file, a scene key, an array
//   incise.Diverged    (incise.Error)            a simulation that diverged (it stops there)
// An internal invariant broken (a bug) is incise.Error too: the interpreter never crashes.

#include "bindings.hpp"
#include "incise/core/error.hpp"

namespace incise::python {
namespace {

// Made once at import and kept for the interpreter's life (the module holds them too).
PyObject* error_type = nullptr;
PyObject* input_error_type = nullptr;
PyObject* diverged_type = nullptr;

}  // namespace

py::handle diverged_error() {
  return diverged_type;
}

void bind_errors(py::module_& module) {
  error_type = PyErr_NewExceptionWithDoc("incise.Error",
                                         "Anything incise refuses or fails at; the message "
                                         "says what, and where (file, line, key, element).",
                                         PyExc_RuntimeError, nullptr);
  const py::tuple input_bases =
      py::make_tuple(py::handle(error_type), py::handle(PyExc_ValueError));
  input_error_type = PyErr_NewExceptionWithDoc(
      "incise.InputError",
      "Bad input: a file, a scene or plan key, an array. The message names the file, the line, "
      "the key or the element, as the command line does.",
      input_bases.ptr(), nullptr);
  diverged_type = PyErr_NewExceptionWithDoc(
      "incise.Diverged",
      "The simulation diverged: the message says where. It stays at the last good frame and "
      "steps no further.",
      error_type, nullptr);
  if (error_type == nullptr || input_error_type == nullptr || diverged_type == nullptr) {
    throw py::error_already_set();
  }
  module.add_object("Error", py::handle(error_type));
  module.add_object("InputError", py::handle(input_error_type));
  module.add_object("Diverged", py::handle(diverged_type));
  py::register_exception_translator([](std::exception_ptr thrown) {
    try {
      if (thrown) {
        std::rethrow_exception(thrown);
      }
    } catch (const InputError& error) {
      PyErr_SetString(input_error_type, error.what());
    } catch (const Error& error) {
      PyErr_SetString(error_type, error.what());
    }
  });
}

}  // namespace incise::python
