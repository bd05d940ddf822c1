"""Meshes: arrays in and out, files, meshio both ways, info and validation."""

import numpy as np
import pytest

import incise


def test_arrays_round_trip_without_copies():
    box = incise.Mesh.box(size=(0.02, 0.03, 0.04), cells=(2, 3, 4))
    assert box.vertices.shape == (3 * 4 * 5, 3) and box.vertices.dtype == np.float64
    assert box.tets.shape == (2 * 3 * 4 * 6, 4)
    # Views of the mesh's own memory: the same memory twice, and read-only.
    assert np.shares_memory(box.vertices, box.vertices)
    assert not box.vertices.flags.writeable and not box.tets.flags.writeable
    with pytest.raises(ValueError):
        box.vertices[0, 0] = 1.0
    rebuilt = incise.Mesh(box.vertices, box.tets, np.arange(box.tet_count) % 3)
    assert np.array_equal(rebuilt.vertices, box.vertices)
    assert np.array_equal(rebuilt.tets, box.tets)
    assert np.array_equal(rebuilt.labels, np.arange(box.tet_count) % 3)
    assert rebuilt.volume == pytest.approx(0.02 * 0.03 * 0.04, rel=1e-12)


def test_a_view_outlives_its_mesh():
    vertices = incise.Mesh.box(cells=(3, 3, 3)).vertices  # the mesh itself is gone
    expected = incise.Mesh.box(cells=(3, 3, 3)).vertices.copy()
    assert np.array_equal(vertices, expected)


def test_files_and_meshio_both_ways(tmp_path):
    import meshio

    box = incise.Mesh.box(size=(0.1, 0.1, 0.1), cells=(3, 2, 2))
    labelled = incise.Mesh(box.vertices, box.tets, (np.arange(box.tet_count) >= 12).astype(int))
    for name in ("a.vtu", "a.msh", "a.mesh"):
        labelled.write(tmp_path / name, unit="m")
        back = incise.Mesh.read(tmp_path / name)
        assert np.array_equal(back.tets, labelled.tets), name
        assert np.allclose(back.vertices, labelled.vertices, rtol=0, atol=1e-12), name
        assert np.array_equal(back.labels, labelled.labels), name
    # An independent reader opens the same files.
    for name in ("a.vtu", "a.mesh"):
        read = meshio.read(tmp_path / name)
        assert sum(len(block.data) for block in read.cells if block.type == "tetra") == box.tet_count
    as_meshio = labelled.to_meshio()
    again = incise.Mesh.from_meshio(as_meshio)
    assert np.array_equal(again.tets, labelled.tets)
    assert np.array_equal(again.labels, labelled.labels)
    meshio.write(tmp_path / "m.vtu", as_meshio)
    meshio.write(tmp_path / "m.msh", meshio.Mesh(as_meshio.points, as_meshio.cells), file_format="gmsh22", binary=False)
    assert incise.Mesh.read(tmp_path / "m.msh").tet_count == labelled.tet_count
    assert incise.Mesh.read(tmp_path / "m.vtu").tet_count == labelled.tet_count


def test_info_and_validation():
    box = incise.Mesh.box(size=(0.04, 0.06, 0.04), cells=(4, 6, 4))
    info = box.info()
    assert info["tets"] == 576 and info["valid"] and info["watertight"]
    assert info["volume"] == pytest.approx(0.04 * 0.06 * 0.04)
    assert info["components"] == 1
    report = box.validate()
    assert report["valid"] and report["inverted_tets"] == []
    # An inverted tetrahedron, built unchecked, is named by validate().
    tets = np.array(box.tets)
    tets[7, [0, 1]] = tets[7, [1, 0]]
    bad = incise.Mesh(box.vertices, tets, check=False)
    assert 7 in bad.validate()["inverted_tets"]
    assert not bad.info()["valid"]


def test_surfaces_and_blade_paths(tmp_path):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    points, triangles = incise.read_surface(tmp_path / "tri.obj")
    assert points.shape == (4, 3) and triangles.shape == (4, 3)
    (tmp_path / "p.csv").write_text("t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n0,0,0,0,0,0,1\n1,1,0,0,1,0,1\n")
    path = incise.read_blade_path(tmp_path / "p.csv")
    assert path.shape == (2, 7) and path[1, 1] == 1.0
