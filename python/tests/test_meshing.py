"""Surfaces to bodies from Python: broken surfaces repaired, meshed and cut apart, as
`incise mesh` does; slivers collapsed as `incise convert --fix-slivers` does."""

import numpy as np
import pytest

import incise

CORNERS = np.array([[x, y, z] for z in (0.0, 0.1) for y in (0.0, 0.1) for x in (0.0, 0.1)])
QUADS = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
TRIANGLES = np.array([t for a, b, c, d in QUADS for t in ((a, b, c), (a, c, d))])
BLADE = [[0.0, 0.05, -0.02, -0.02, 0.05, -0.02, 0.12], [1.0, 0.05, 0.12, -0.02, 0.05, 0.12, 0.12]]


def _body_cut_apart(surface, blade=BLADE, **options):
    mesh, report = incise.mesh_surface(surface, max_volume=2e-5, **options)
    info = mesh.info()
    assert info["valid"] and info["watertight"], info
    cut, cut_report = incise.cut(mesh, blade)
    assert cut_report["components"] == 2
    return mesh, report


@pytest.mark.parametrize("defect", ["clean", "hole", "flipped", "duplicated", "inward"])
def test_broken_boxes_become_bodies_that_cut_apart(defect):
    triangles = TRIANGLES.copy()
    if defect == "hole":
        triangles = triangles[1:]
    elif defect == "flipped":
        triangles[3] = triangles[3][::-1]
    elif defect == "duplicated":
        triangles = np.vstack([triangles, triangles[:2]])
    elif defect == "inward":
        triangles = triangles[:, ::-1]
    mesh, report = _body_cut_apart((CORNERS, triangles))
    assert mesh.volume == pytest.approx(1e-3, rel=1e-6)
    assert report["repair"]["changed"] == (defect != "clean")
    if defect == "hole":
        assert report["repair"]["holes_filled"] == 1
        assert report["repair"]["hole_area"] == pytest.approx(0.005, rel=1e-6)


def test_a_refused_surface_says_why_and_a_wrap_closes_it():
    overlapping = (np.vstack([CORNERS, CORNERS + 0.05]),
                   np.vstack([TRIANGLES, TRIANGLES + 8]))  # two boxes through each other
    with pytest.raises(incise.InputError):
        incise.mesh_surface(overlapping, repair="none")
    through_both = [[0.0, 0.07, -0.02, -0.02, 0.07, -0.02, 0.2], [1.0, 0.07, 0.2, -0.02, 0.07, 0.2, 0.2]]
    mesh, report = _body_cut_apart(overlapping, blade=through_both, repair="wrap")
    assert report["repair"]["wrapped"]
    assert report["repair"]["result_to_input"] <= report["repair"]["offset"] * 1.5 + 1e-9


def test_the_liver_surface_from_a_file(source_dir):
    liver = source_dir.parent / "shared" / "data" / "sofa" / "liver-smooth.obj"
    if not liver.exists():
        pytest.skip("../shared/data is not beside the source tree")
    mesh, report = incise.mesh_surface(liver)
    assert mesh.info()["valid"] and mesh.tet_count > 1000
    assert report["shells"] >= 1


def test_bad_surfaces_and_options_are_named():
    with pytest.raises(incise.InputError, match="surface triangles"):
        incise.mesh_surface((CORNERS, [[0, 1, 9]]))
    with pytest.raises(incise.InputError, match="repair"):
        incise.mesh_surface((CORNERS, TRIANGLES), repair="glue")
    with pytest.raises(incise.InputError, match="min_quality"):
        incise.mesh_surface((CORNERS, TRIANGLES), min_quality=0.5)
    with pytest.raises(incise.InputError, match="a file's path"):
        incise.mesh_surface(42)


def test_fix_slivers_keeps_a_clean_mesh_as_it_is():
    box = incise.Mesh.box(cells=(3, 3, 3))
    fixed, report = box.fix_slivers()
    assert report["collapses"] == 0 and report["slivers_after"] == 0
    assert np.array_equal(fixed.tets, box.tets)
