"""Meshes to and from meshio (Debian's python3-meshio), which reads and writes Gmsh, VTK,
MEDIT, Abaqus, Exodus and more."""

import numpy as np


def to_meshio(mesh):
    """The mesh as a ``meshio.Mesh``: its points (rest positions) and one ``tetra`` cell block,
    with the region labels as the cell data ``labels``."""
    import meshio

    return meshio.Mesh(
        points=np.array(mesh.vertices),
        cells=[("tetra", np.array(mesh.tets))],
        cell_data={"labels": [np.array(mesh.labels)]},
    )


def from_meshio(meshio_mesh, labels=None, check=True):
    """An ``incise.Mesh`` from a ``meshio.Mesh``: its tetrahedra (other cells are left out) and,
    if present, the integer cell data named ``labels`` (default: ``labels``, else
    ``gmsh:physical``, else ``medit:ref``) as region labels. Points no tetrahedron uses are
    dropped. Raises InputError if there are no tetrahedra."""
    from ._incise import InputError, Mesh

    blocks = [i for i, block in enumerate(meshio_mesh.cells) if block.type == "tetra"]
    if not blocks:
        kinds = sorted({block.type for block in meshio_mesh.cells})
        raise InputError(f"from_meshio: no tetra cells (the mesh has {kinds or 'no cells'})")
    tets = np.concatenate([np.asarray(meshio_mesh.cells[i].data, dtype=np.int64) for i in blocks])
    names = [labels] if labels else ["labels", "gmsh:physical", "medit:ref"]
    region = None
    for name in names:
        if name in meshio_mesh.cell_data:
            region = np.concatenate(
                [np.asarray(meshio_mesh.cell_data[name][i]).reshape(-1) for i in blocks]
            )
            break
    else:
        if labels:
            raise InputError(
                f"from_meshio: no cell data named {labels!r} "
                f"(it has {sorted(meshio_mesh.cell_data)})"
            )
    points = np.asarray(meshio_mesh.points, dtype=np.float64)
    if points.ndim == 2 and points.shape[1] == 2:
        raise InputError("from_meshio: the points are 2-D; a tetrahedral mesh needs 3-D points")
    used = np.unique(tets)
    if used.size and (used[0] < 0 or used[-1] >= len(points)):
        raise InputError("from_meshio: a tetrahedron refers to a point the mesh does not have")
    if used.size != len(points):
        remap = np.full(len(points), -1, dtype=np.int64)
        remap[used] = np.arange(used.size)
        points = points[used]
        tets = remap[tets]
    return Mesh(points, tets, region, check=check)
