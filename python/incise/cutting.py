"""Cutting without physics from Python: ``incise.cut``."""

import json
import os

import numpy as np

from ._incise import InputError, Mesh, _cut_subdivision, read_blade_path


def cut(mesh, blade, method="subdivision", snap=0.1, split="minimal", merge_blade_points=False,
        unit=None):
    """Cuts a mesh along a whole blade path, as ``incise cut`` does: the same cutter, every pose
    checked, the same report.

    mesh: an ``incise.Mesh`` or a mesh file's path. blade: a blade-path CSV's path or an (n, 7)
    array of poses (t in s, tip x y z, base x y z in the mesh's unit). method: 'subdivision'
    (Bielser et al.'s progressive subdivision; the only one here so far: XFEM cuts of files are
    ``incise cut --method xfem``). snap: crossings within this fraction of an edge snap to its
    vertex. split: 'minimal' or 'generic'. unit: 'm', 'cm' or 'mm', said in the report.

    Returns (cut mesh, report dict). Raises InputError for a mesh that cannot be cut or a cut
    that leaves an invalid mesh (naming the pose and the problem). The GIL is released while it
    cuts."""
    if method != "subdivision":
        raise InputError(
            f"method: {method!r}: incise.cut does the subdivision cut; the XFEM cut of a file is "
            "`incise cut --method xfem` for now"
        )
    mesh_name = "<Mesh>"
    if not isinstance(mesh, Mesh):
        mesh_name = os.fspath(mesh)
        mesh = Mesh.read(mesh_name)
    blade_name = "<array>"
    if isinstance(blade, (str, os.PathLike)):
        blade_name = os.fspath(blade)
        blade = read_blade_path(blade_name)
    units = {None: "mesh units", "m": "m", "cm": "cm", "mm": "mm"}
    if unit not in units:
        raise InputError(f"unit: {unit!r} is none of m, cm, mm")
    result, report, invalid, problem = _cut_subdivision(
        mesh, np.asarray(blade, dtype=np.float64), snap, split, merge_blade_points, mesh_name,
        blade_name, units[unit]
    )
    if invalid:
        raise InputError(f"the cut left an invalid mesh {problem}")
    return result, json.loads(report)
