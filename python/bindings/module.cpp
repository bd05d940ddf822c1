// _incise: the compiled core of the incise package (python/incise/__init__.py re-exports it).

#include "bindings.hpp"

PYBIND11_MODULE(_incise, module) {
  module.doc() =
      "incise's compiled core: tetrahedral meshes, simulations that step, cut and render, "
      "cutting without physics and surgical planning. Units are SI throughout: m, s, kg, N, "
      "Pa, kg/m^3.";
  incise::python::bind_errors(module);
  incise::python::bind_mesh(module);
  incise::python::bind_simulation(module);
  incise::python::bind_cutting(module);
  incise::python::bind_meshing(module);
  incise::python::bind_planning(module);
}
