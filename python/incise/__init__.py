"""incise: interactive cutting and deformation of 3-D soft tissue, from Python.

Three lines::

    import incise
    sim = incise.Simulation("scenes/default.json")   # a path, a dict of scene keys, or None
    frames = sim.step(10)                             # Frame records; sim.positions is (n, 3)

What is here (units are SI throughout: m, s, kg, N, Pa, kg/m^3):

- ``Mesh``: read, write, generate (``Mesh.box``), validate, ``info()``; arrays in and out;
  ``to_meshio`` / ``from_meshio``.
- ``Simulation``: step, blade poses (``set_blade`` / ``lift_blade``), ``push``, arrays that
  never go stale, ``save_state`` / ``restore`` for episodes, ``checkpoint`` / ``Simulation.resume``
  for files, ``render`` for pictures.
- ``mesh_surface``: a triangle surface (repaired if it must be) tetrahedralised, as ``incise mesh``.
- ``cut``: a mesh cut along a blade path without physics, with the ``incise cut`` report.
- ``plan``: surgical planning from CT (a plan file or dict), the skin before and after;
  ``PlanSession``: a plan prepared once, bone segments moved and the face predicted after each.
- ``sweep``: a table of scene variants through Dask, one row per variant (pandas).
- ``CutAlongLineEnv``: a reinforcement-learning task with the Gymnasium API.

Errors are ``incise.InputError`` (bad input; also a ValueError), ``incise.Diverged`` and
``incise.Error`` with the command line's messages.
"""

from ._incise import (  # noqa: F401  (the compiled core)
    Diverged,
    Error,
    Frame,
    InputError,
    Mesh,
    PlanSession,
    Simulation,
    mesh_surface,
    read_blade_path,
    read_surface,
)
from .cutting import cut  # noqa: F401
from .meshes import from_meshio, to_meshio  # noqa: F401
from .planning import plan  # noqa: F401
from .sweep import sweep  # noqa: F401
from .environment import CutAlongLineEnv  # noqa: F401

def _fix_slivers(self):
    """A copy with the flat tetrahedra and slivers collapsed away where that keeps the boundary
    (within a thousandth of the sliver's longest edge), as `incise convert --fix-slivers` does:
    (mesh, report with the counts before and after and the largest boundary shift)."""
    from ._incise import _fix_slivers as fix

    return fix(self)


Mesh.fix_slivers = _fix_slivers  # type: ignore[assignment]
Mesh.to_meshio = to_meshio  # type: ignore[assignment]  # declared in _incise.pyi
Mesh.from_meshio = staticmethod(from_meshio)  # type: ignore[assignment]

__all__ = [
    "CutAlongLineEnv",
    "Diverged",
    "Error",
    "Frame",
    "InputError",
    "Mesh",
    "PlanSession",
    "Simulation",
    "cut",
    "from_meshio",
    "mesh_surface",
    "plan",
    "read_blade_path",
    "read_surface",
    "sweep",
    "to_meshio",
]
