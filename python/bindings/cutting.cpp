// incise.cut's compiled half: a mesh cut along a blade path without physics.

#include "bindings.hpp"

namespace incise::python {

void bind_cutting(py::module_& /*module*/) {}

}  // namespace incise::python
