"""Cutting without physics, planning and the reinforcement-learning task (sweeps: test_sweep.py)."""

import json
import subprocess

import numpy as np
import pytest

import incise

PLANAR_BLADE = [[0.0, 0.05, -0.02, -0.02, 0.05, -0.02, 0.12],
                [1.0, 0.05, 0.12, -0.02, 0.05, 0.12, 0.12]]


def test_cut_separates_and_matches_the_command_line(tmp_path, incise_executable):
    box = incise.Mesh.box(size=(0.1, 0.1, 0.1), cells=(5, 5, 5))
    cut, report = incise.cut(box, PLANAR_BLADE, unit="m")
    assert report["components"] == 2 and report["valid"] and report["watertight"]
    assert cut.info()["components"] == 2
    assert cut.volume == pytest.approx(box.volume, rel=1e-9)
    # The same cut by `incise cut`: the same report, the same tetrahedra.
    box.write(tmp_path / "box.vtu")
    lines = ["t,tip_x,tip_y,tip_z,base_x,base_y,base_z"] + [",".join(map(repr, p)) for p in PLANAR_BLADE]
    (tmp_path / "blade.csv").write_text("\n".join(lines) + "\n")
    subprocess.run([incise_executable, "cut", str(tmp_path / "box.vtu"), "--blade",
                    str(tmp_path / "blade.csv"), "-o", str(tmp_path / "cut.vtu"), "--report",
                    str(tmp_path / "r.json"), "--unit", "m"], check=True, capture_output=True)
    command_line = json.loads((tmp_path / "r.json").read_text())
    for key in ("tets_out", "vertices_out", "components", "cut_faces", "edges_split", "cut_area"):
        assert report[key] == command_line[key], key
    assert np.array_equal(incise.Mesh.read(tmp_path / "cut.vtu").tets, cut.tets)


def test_xfem_cut_with_a_visual_surface_matches_the_command_line(tmp_path, incise_executable):
    box = incise.Mesh.box(size=(0.1, 0.1, 0.1), cells=(4, 4, 4))
    # The visual surface: a closed box inside the mesh, 2 cells across.
    lo, hi = 0.02, 0.08
    corners = np.array([[x, y, z] for z in (lo, hi) for y in (lo, hi) for x in (lo, hi)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    triangles = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    virtual, report = incise.cut(box, PLANAR_BLADE, method="xfem", unit="m",
                                 visual=(corners, triangles), out_dir=tmp_path / "py")
    assert report["components"] == 2 and report["method"] == "xfem"
    weighted = float(np.sum(virtual.fractions * np.array(
        [abs(np.linalg.det(virtual.vertices[t[1:]] - virtual.vertices[t[0]])) / 6 for t in virtual.tets])))
    assert weighted == pytest.approx(box.volume, rel=1e-9)
    points, cut_triangles = report["visual_cut"]
    assert report["visual_surface"]["closed_manifold"] and len(cut_triangles) > len(triangles)
    # The same cut from the command line.
    box.write(tmp_path / "box.vtu")
    with open(tmp_path / "visual.obj", "w") as obj:
        obj.writelines(f"v {x} {y} {z}\n" for x, y, z in corners)
        obj.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in triangles)
    lines = ["t,tip_x,tip_y,tip_z,base_x,base_y,base_z"] + [",".join(map(repr, p)) for p in PLANAR_BLADE]
    (tmp_path / "blade.csv").write_text("\n".join(lines) + "\n")
    subprocess.run([incise_executable, "cut", str(tmp_path / "box.vtu"), "--blade",
                    str(tmp_path / "blade.csv"), "--method", "xfem", "-o", str(tmp_path / "cut.vtu"),
                    "--visual", str(tmp_path / "visual.obj"), "--visual-out", str(tmp_path / "v.vtp"),
                    "--report", str(tmp_path / "r.json"), "--unit", "m"], check=True, capture_output=True)
    command_line = json.loads((tmp_path / "r.json").read_text())
    for key in ("tets_out", "vertices_out", "components", "elements_split", "dofs_added",
                "volume_out", "clipped_volume", "visual_volume_out"):
        assert report[key] == command_line[key], key


def test_plan_from_the_example_ct(source_dir, tmp_path):
    stages = []
    result = incise.plan(source_dir / "scenes" / "plan_headsq.json", out_dir=tmp_path,
                         progress=lambda stage, fraction: stages.append((stage, fraction)))
    assert result["skin_before"].shape == result["skin_after"].shape
    assert result["skin_triangles"].max() < len(result["skin_before"])
    moved = np.linalg.norm(result["skin_after"] - result["skin_before"], axis=1).max()
    assert moved * 1e3 == pytest.approx(result["max_displacement_mm"], rel=1e-6)
    assert result["report"]["stages"] if "stages" in result["report"] else result["report"]
    points, triangles = result["bone_after"]
    assert len(points) > 0 and len(triangles) > 0
    assert stages and stages[-1][1] == pytest.approx(1.0)


def test_a_plan_session_moves_a_segment_stops_at_contact_and_saves_what_plan_reproduces(
        source_dir, tmp_path):
    """incise.PlanSession, what incise plan --view drives: the example CT's plan prepared once,
    its segment moved and predicted warm, a push through the cut refused, and the plan saved
    with the move run by incise.plan to the session's cold prediction."""
    path = source_dir / "scenes" / "plan_headsq.json"
    plan = json.loads(path.read_text())
    move = plan["moves"][0]
    plan["moves"] = []
    session = incise.PlanSession(plan, plan_file=path)
    assert session.segments >= 2 and len(session.segment_volumes_mm3) == session.segments
    assert session.predict()["converged"]
    assert np.abs(session.skin_after - session.skin_before).max() < 5e-4  # m: nothing moved
    segment = session.segment_near(move["segment_near"])
    assert session.move(segment, translate_mm=move["translate"]) == []
    warm = session.predict(warm=True)
    assert warm["converged"]
    # Where the time went, and how many factorisations it took (the session keeps the last).
    assert set(warm["stage_seconds"]) == {"assembly", "factorization", "solve", "line_search"}
    assert 0 <= warm["lagged_steps"] <= warm["iterations"]
    assert len(warm["steps"]) == warm["iterations"]
    assert sum(step["lagged"] for step in warm["steps"]) == warm["lagged_steps"]
    assert warm["factorizations"] >= 0
    assert warm["pattern_analyses"] == 0  # the equilibrium's analysis of the same pattern
    after_warm = session.skin_after.copy()
    assert np.linalg.norm(after_warm - session.skin_before, axis=1).max() > 2e-3
    # Pushed 8 mm down through its cut: refused, naming the pair; the last move stays.
    refused = session.move(segment, translate_mm=[0, 0, -8])
    assert refused and segment in refused[0]["segments"] and refused[0]["depth_mm"] > 0.5
    cold = session.predict(warm=False)
    assert cold["converged"]
    assert np.abs(session.skin_after - after_warm).max() < 1e-5
    saved = session.plan_with_moves(plan)
    assert len(saved["moves"]) == 1 and saved["moves"][0]["translate"] == move["translate"]
    result = incise.plan(saved, out_dir=tmp_path, plan_file=path)
    assert np.abs(result["skin_after"] - session.skin_after).max() < 1e-12
    with pytest.raises(incise.InputError, match="no bone segment"):
        session.move(session.segments, translate_mm=[1, 0, 0])


def test_a_plan_from_a_dict_and_its_bad_keys(source_dir, tmp_path):
    path = source_dir / "scenes" / "plan_headsq.json"
    plan = json.loads(path.read_text())
    plan["moves"] = []  # nothing moved: the face stays where it was
    result = incise.plan(plan, out_dir=tmp_path, plan_file=path)
    assert result["max_displacement_mm"] < 0.5
    with pytest.raises(incise.InputError, match="'isos'.*did you mean 'iso'"):
        incise.plan(dict(plan, isos=plan["iso"]), out_dir=tmp_path, plan_file=path)


def test_the_environment_is_deterministic_for_a_seed():
    env = incise.CutAlongLineEnv(max_steps=12)

    def episode(seed):
        obs, info = env.reset(seed=seed)
        actions = np.random.default_rng(seed).uniform(-1, 1, size=(12, 2))
        actions[:, 1] = 1.0  # forward through the block
        observations, rewards = [obs], []
        for action in actions:
            obs, reward, terminated, truncated, info = env.step(action)
            observations.append(obs)
            rewards.append(reward)
            if terminated or truncated:
                break
        return np.array(observations), rewards, info

    first = episode(3)
    other = episode(4)
    again = episode(3)
    assert np.array_equal(first[0], again[0]) and first[1] == again[1]
    assert first[2]["target_x"] != other[2]["target_x"]
    assert first[2]["tets"] > 576  # the blade cut the block
    assert env.observation_space.contains(first[0][-1])
    assert env.action_space.contains(env.action_space.sample(np.random.default_rng(0)))
    picture = env.render()
    assert picture.shape == (env.height, env.width, 3)
    pixels = incise.CutAlongLineEnv(observation="pixels", max_steps=3)
    obs, _ = pixels.reset(seed=1)
    assert obs.shape == (72, 96, 3) and obs.dtype == np.uint8
    assert pixels.observation_space.contains(obs)
    after, *_ = pixels.step((0.0, 1.0))
    assert not np.array_equal(after, obs)  # the blade moved in the picture


def test_a_segment_slid_along_its_osteotomy_on_a_ct_is_predicted(source_dir, tmp_path):
    """The issue's test: a synthetic head CT (bench/head_phantom.py, with skin relief, cancellous
    bone, a sinus, the scanner's table), the maxilla cut by a Le Fort I-like plane and advanced
    5 mm along its own cut. The move predicts (it was refused as interpenetration); the bones
    the default seeding missed are there; fragments are merged; segments carry volumes."""
    subprocess.run(["/usr/bin/python3", str(source_dir / "bench" / "head_phantom.py"),
                    str(tmp_path), "--size", "128", "128", "60", "--spacing", "2", "2", "4",
                    "--dicom"], check=True, capture_output=True)
    # The CT as a scanner gives it: a DICOM series, read in Hounsfield units (the plan's iso
    # values with them; the MetaImage plan below holds the stored numbers, 1024 higher).
    dicom_plan = json.loads((tmp_path / "plan_dicom.json").read_text())
    assert dicom_plan["iso"] == {"skin": 500 - 1024, "bone": 1600 - 1024}
    result = incise.plan(dicom_plan, out_dir=tmp_path / "out",
                         plan_file=tmp_path / "plan_dicom.json")
    report = result["report"]
    assert report["converged"]
    assert 3.0 < result["max_displacement_mm"] < 8.0, "the face follows the 5 mm advance"
    segments = report["segment_list"]
    moved = [s for s in segments if s["moved"]]
    assert len(moved) == 1 and moved[0]["volume_mm3"] > 1000.0
    assert all(s["volume_mm3"] >= report["min_segment_volume_mm3"] for s in segments)
    # Skull with maxilla, mandible and vertebra are kept; the table and cavities are not.
    components = report["image"]["components"]
    assert components["bone"]["kept"] >= 3
    assert components["skin"]["kept"] == 1
    distance = report["image"]["surface_distance_mm"]["skin"]
    assert distance["model_to_isosurface"]["p99"] <= distance["bound"] * 1.5
    # The closed airway's wall is counted apart, not as the model's error (before, such walls
    # put the isosurface-to-model p99 at 8.6 mm on the 256 x 256 x 113 phantom).
    assert distance["isosurface_to_model"]["samples_on_enclosed_cavities"] > 0
    assert distance["isosurface_to_model"]["p99"] <= distance["bound"] * 3
    assert report["image"]["read"].startswith("DICOM"), report["image"]["read"]
    # The same move pushed 3 mm into the skull through the cut is refused before building.
    plan = json.loads((tmp_path / "plan.json").read_text())
    plan["moves"][0]["translate"] = [0, 0, 3]
    with pytest.raises(incise.InputError, match="interpenetrate"):
        incise.plan(plan, out_dir=tmp_path / "refused", plan_file=tmp_path / "plan.json")
    # The stored numbers' iso values on the series (Hounsfield units) miss the bone: a clear
    # refusal naming the key and the image's range (it was a CGAL precondition failure).
    dicom_plan["iso"] = {"skin": 500, "bone": 1600}
    with pytest.raises(incise.InputError, match=r"iso\.bone.*Hounsfield"):
        incise.plan(dicom_plan, out_dir=tmp_path / "units", plan_file=tmp_path / "plan_dicom.json")
