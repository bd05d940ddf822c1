"""Every bad input raises incise.InputError (or another Python exception), naming what is
wrong; none crashes the interpreter. Fuzzed with random arrays of every wrong kind."""

import numpy as np
import pytest

import incise

BOX = incise.Mesh.box(cells=(2, 2, 2))


@pytest.mark.parametrize(
    "vertices, tets, match",
    [
        (np.zeros((4, 2)), [[0, 1, 2, 3]], r"vertices: an \(n, 3\) array"),
        (np.zeros(12), [[0, 1, 2, 3]], r"vertices: an \(n, 3\) array"),
        ([[0, 0, 0], [1, 0, 0], [0, np.nan, 0], [0, 0, 1]], [[0, 1, 2, 3]], "row 2 is not finite"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, np.inf]], [[0, 1, 2, 3]], "row 3 is not finite"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 2, -1]], "refers to vertex -1"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 2, 4]], "refers to vertex 4"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 2]], r"tets: an \(n, 4\) array"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 2, 2]], "uses vertex 2 twice"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1, 3]], "inverted"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 2, 0]], [[0, 1, 2, 3]], "degenerate"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 2.5, 3]], "not a whole number"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.zeros((0, 4)), "at least one"),
        ([["a", "b", "c"]], [[0, 1, 2, 3]], "numbers are needed"),
        ("vertices", [[0, 1, 2, 3]], r"vertices"),
    ],
)
def test_bad_mesh_arrays_are_named(vertices, tets, match):
    with pytest.raises(incise.InputError, match=match):
        incise.Mesh(vertices, tets)


def test_bad_labels_and_files(tmp_path):
    with pytest.raises(incise.InputError, match="one label per tetrahedron"):
        incise.Mesh(BOX.vertices, BOX.tets, [1, 2, 3])
    with pytest.raises(incise.InputError, match="no.such"):
        incise.Mesh.read(tmp_path / "no.such.msh")
    (tmp_path / "bad.msh").write_text("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\nnonsense\n")
    with pytest.raises(incise.InputError, match="bad.msh"):
        incise.Mesh.read(tmp_path / "bad.msh")
    with pytest.raises(incise.InputError, match="unit"):
        BOX.write(tmp_path / "x.vtu", unit="furlong")
    with pytest.raises(incise.InputError):
        BOX.write(tmp_path / "x.unknown")


def test_bad_scenes_name_the_key(tmp_path):
    with pytest.raises(incise.InputError, match="'materail'.*did you mean 'material'"):
        incise.Simulation({"materail": "liver"})
    with pytest.raises(incise.InputError, match="frames"):
        incise.Simulation({"mesh": {"box": {"cells": [1, 1, 1]}}, "frames": "many"})
    (tmp_path / "s.json").write_text('{"mesh": {"box": {"cells": [1, 1, 1]}},\n "integrator": {"dt": -1}}')
    with pytest.raises(incise.InputError, match=r"s\.json:2"):
        incise.Simulation(tmp_path / "s.json")
    with pytest.raises(incise.InputError, match="a path, a dict or None"):
        incise.Simulation(42)
    with pytest.raises(incise.InputError):
        incise.Simulation(tmp_path / "missing.json")


def test_bad_calls_on_a_simulation():
    sim = incise.Simulation()
    with pytest.raises(incise.InputError, match="0 or more"):
        sim.step(-1)
    assert sim.step(0) == []
    with pytest.raises(incise.InputError, match="not an incise checkpoint"):
        sim.restore(b"garbage")
    state = bytearray(sim.save_state())
    state[len(state) // 2] ^= 0xFF
    with pytest.raises(incise.InputError, match="checksum"):
        sim.restore(bytes(state))
    with pytest.raises(incise.InputError, match="truncated"):
        sim.restore(sim.save_state()[:-7])
    with pytest.raises(incise.InputError, match="tip"):
        sim.set_blade((np.nan, 0, 0), (0, 0, 1))
    with pytest.raises(incise.InputError, match="same point"):
        sim.set_blade((0, 0, 0), (0, 0, 0))
    with pytest.raises(incise.InputError, match="frame"):
        sim.set_blade((0, 0, 0), (0, 0, 1), frame="sideways")
    with pytest.raises(incise.InputError, match="mode"):
        sim.render(10, 10, mode="x-ray")
    with pytest.raises(incise.InputError, match="size"):
        sim.render(0, 10)
    with pytest.raises(incise.InputError, match="barycentric"):
        sim.push(0, (2, -1, 0), (0, 0, 1))
    sim.step(2)  # still usable after every refusal
    assert sim.frame == 2


def test_cut_refuses_bad_blades():
    with pytest.raises(incise.InputError, match=r"\(n, 7\)"):
        incise.cut(BOX, np.zeros((3, 6)))
    with pytest.raises(incise.InputError, match="not finite"):
        incise.cut(BOX, [[0, np.nan, 0, 0, 0, 0, 1]])
    with pytest.raises(incise.InputError, match="back in time"):
        incise.cut(BOX, [[1, 0, 0, 0, 0, 0, 1], [0, 0, 0, 0, 0, 0, 1]])
    with pytest.raises(incise.InputError, match="method"):
        incise.cut(BOX, [[0, 0, 0, 0, 0, 0, 1]], method="laser")
    with pytest.raises(incise.InputError, match="visual triangles"):
        incise.cut(BOX, [[0, 0, 0, 0, 0, 0, 1]], method="xfem",
                   visual=(np.zeros((3, 3)), [[0, 1, 5]]))
    with pytest.raises(incise.InputError, match="method='xfem' only"):
        incise.cut(BOX, [[0, 0, 0, 0, 0, 0, 1]], visual=(np.zeros((3, 3)), [[0, 1, 2]]))


def test_fuzzed_arrays_never_crash():
    rng = np.random.default_rng(7)
    kinds = [np.float64, np.float32, np.int64, np.int8, np.uint16, np.bool_, object]
    refused = 0
    for trial in range(400):
        n = int(rng.integers(0, 9))
        shape_v = [(n, 3), (n, 2), (n,), (n, 3, 1), (n, 4)][int(rng.integers(0, 5))]
        vertices = rng.normal(size=shape_v) * 10.0 ** rng.integers(-3, 3)
        if rng.random() < 0.2 and vertices.size:
            vertices.flat[int(rng.integers(0, vertices.size))] = [np.nan, np.inf, -np.inf][trial % 3]
        m = int(rng.integers(0, 5))
        shape_t = [(m, 4), (m, 3), (m,), (m, 4, 2)][int(rng.integers(0, 4))]
        tets = rng.integers(-3, n + 3, size=shape_t).astype(kinds[trial % len(kinds)])
        try:
            mesh = incise.Mesh(vertices, tets)
        except (incise.InputError, TypeError, ValueError):
            refused += 1
            continue
        assert mesh.tet_count == len(tets) and mesh.info()["valid"]
    assert refused > 300


def test_fuzzed_calls_on_a_simulation_never_crash():
    rng = np.random.default_rng(11)
    sim = incise.Simulation()
    state = sim.save_state()
    values = [np.nan, np.inf, -1e300, 0.0, 1e-300, 3, "x", None, [], [1, 2], [[1, 2, 3]],
              np.zeros((2, 3)), np.ones(3, dtype=np.int8), np.array([1, 2, 3], dtype=object)]
    pick = lambda: values[int(rng.integers(0, len(values)))]
    for trial in range(300):
        call = trial % 5
        try:
            if call == 0:
                sim.set_blade(pick(), pick(), frame=["rest", "world", "up"][trial % 3])
            elif call == 1:
                sim.push(int(rng.integers(-2, 5)), pick(), pick())
            elif call == 2:
                broken = bytearray(state)
                for _ in range(int(rng.integers(1, 4))):
                    broken[int(rng.integers(0, len(broken)))] = int(rng.integers(0, 256))
                sim.restore(bytes(broken[: int(rng.integers(0, len(broken) + 1))]))
            elif call == 3:
                sim.render(int(rng.integers(-5, 40)), int(rng.integers(-5, 40)), mode=["faces", "wire", "cut", "?"][trial % 4])
            else:
                incise.cut(BOX, pick())
        except (incise.Error, TypeError, ValueError, OverflowError):
            pass
    sim.restore(state)
    sim.step(3)
    assert sim.frame == 3
