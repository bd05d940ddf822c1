"""Cutting without physics from Python: ``incise.cut``."""

import json
import os
import pathlib
import tempfile

import numpy as np

from ._incise import InputError, Mesh, _cut_subdivision, _cut_xfem, read_blade_path, read_surface

_UNITS = {None: (None, "mesh units"), "m": (1.0, "m"), "cm": (1e-2, "cm"), "mm": (1e-3, "mm")}


def cut(mesh, blade, method="subdivision", snap=0.1, split="minimal", merge_blade_points=False,
        unit=None, visual=None, out_dir=None):
    """Cuts a mesh along a whole blade path, as ``incise cut`` does: the same cutters, every pose
    checked, the same report.

    mesh: an ``incise.Mesh`` or a mesh file's path. blade: a blade-path CSV's path or an (n, 7)
    array of poses (t in s, tip x y z, base x y z in the mesh's unit). unit: 'm', 'cm' or 'mm',
    said in the report (incise never rescales).

    method 'subdivision' (Bielser et al.'s progressive subdivision): snap (crossings within this
    fraction of an edge snap to its vertex), split ('minimal' or 'generic'),
    merge_blade_points. Returns (the cut mesh, the report dict).

    method 'xfem' (Gutierrez & Ramos' virtual elements): visual (a surface file's path or
    (points, triangles) arrays) is embedded in the mesh and cut with it; the files `incise cut
    --method xfem` writes go to out_dir (a new temporary folder by default): cut.vtu (virtual
    elements with their material `fraction`), cut_clipped.vtu (what ParaView integrates to the
    true volume), visual.vtp. Returns (the virtual elements as a Mesh, whose `fractions` weigh
    them; the report dict, with `output`, and `visual_cut` = (points, triangles) when a visual
    surface was given).

    Raises InputError for a mesh that cannot be cut or a cut that leaves an invalid mesh
    (naming the pose and the problem). The GIL is released while it cuts."""
    if method not in ("subdivision", "xfem"):
        raise InputError(f"method: {method!r} is neither 'subdivision' nor 'xfem'")
    if unit not in _UNITS:
        raise InputError(f"unit: {unit!r} is none of m, cm, mm")
    unit_m, unit_name = _UNITS[unit]
    mesh_name = "<Mesh>"
    if not isinstance(mesh, Mesh):
        mesh_name = os.fspath(mesh)
        mesh = Mesh.read(mesh_name)
    blade_name = "<array>"
    if isinstance(blade, (str, os.PathLike)):
        blade_name = os.fspath(blade)
        blade = read_blade_path(blade_name)
    blade = np.asarray(blade, dtype=np.float64)
    if method == "subdivision":
        if visual is not None:
            raise InputError("visual: a visual surface is cut with method='xfem' only")
        result, report, invalid, problem = _cut_subdivision(
            mesh, blade, snap, split, merge_blade_points, mesh_name, blade_name, unit_name)
        if invalid:
            raise InputError(f"the cut left an invalid mesh {problem}")
        return result, json.loads(report)
    out = pathlib.Path(out_dir if out_dir is not None else tempfile.mkdtemp(prefix="incise-cut-"))
    out.mkdir(parents=True, exist_ok=True)
    visual_out = out / "visual.vtp" if visual is not None else pathlib.Path()
    report = json.loads(_cut_xfem(mesh, blade, visual, out / "cut.vtu", visual_out, unit_m,
                                  mesh_name, blade_name))
    report["output"] = str(out / "cut.vtu")
    if visual is not None:
        report["visual_cut"] = read_surface(visual_out)
    return Mesh.read(out / "cut.vtu"), report
