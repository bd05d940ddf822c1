#pragma once
// The pieces of the _incise module, each bound by its own file: errors, meshes, the
// simulation, cutting without physics, meshing surfaces, planning.

#include <pybind11/pybind11.h>

namespace incise::python {

namespace py = pybind11;

void bind_errors(py::module_& module);
void bind_mesh(py::module_& module);
void bind_simulation(py::module_& module);
void bind_cutting(py::module_& module);
void bind_meshing(py::module_& module);
void bind_planning(py::module_& module);

/// The Python exception type for a simulation that diverged (incise.Diverged).
[[nodiscard]] py::handle diverged_error();

}  // namespace incise::python
