#!/usr/bin/env python3
"""Stepping from Python against `incise run`, and the cost of an episode reset, on the peers'
48k-tetrahedron FEM box (bench/serve_fem_48k.json: corotational FEM, backward Euler, block-Jacobi
CG to 1e-6, sagging under gravity).

    PYTHONPATH=build/release/python python3 bench/python_overhead.py build/release/apps/incise [--frames N] [--rounds R]

Each round runs `incise run` on the scene writing only its first and last frame (its report's
mean cd+gc+rx a frame: the engine's frame without the files it writes) and the same frames through incise.Simulation (the wall time of
sim.step(n) a frame: what a Python caller waits), alternating, so both see the same machine. Reset: sim.save_state() once, then sim.restore(state) timed R times."""

import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import incise

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("incise")
parser.add_argument("--scene", default=str(pathlib.Path(__file__).resolve().parent / "serve_fem_48k.json"))
parser.add_argument("--frames", type=int, default=30)
parser.add_argument("--rounds", type=int, default=3)
args = parser.parse_args()

run_per_frame, python_per_frame, python_wall = [], [], []
with tempfile.TemporaryDirectory() as scratch:
    # The same scene writing only its first and last frame: incise run's files would otherwise
    # cost it cache and time that Python (no sinks) does not pay.
    scene = json.loads(pathlib.Path(args.scene).read_text())
    scene.setdefault("output", {})["vtu_every"] = args.frames + 1
    scene["output"]["dir"] = scratch
    args.scene = str(pathlib.Path(scratch) / "scene.json")
    pathlib.Path(args.scene).write_text(json.dumps(scene))
    for _ in range(args.rounds):
        report = pathlib.Path(scratch) / "r.json"
        started = time.perf_counter()
        subprocess.run([args.incise, "run", args.scene, "--frames", str(args.frames), "--out",
                        scratch, "--report", str(report)],
                       check=True, capture_output=True)
        run_wall = time.perf_counter() - started
        data = json.loads(report.read_text())
        mean = data["mean_ms"]  # the engine's frame without its output (Python has no sinks)
        run_per_frame.append((mean["cd"] + mean["gc"] + mean["rx"]) / 1e3)
        sim = incise.Simulation(args.scene)
        started = time.perf_counter()
        frames = sim.step(args.frames)
        python_wall.append((time.perf_counter() - started) / args.frames)
        python_per_frame.append(sum(f.cd + f.gc + f.rx + f.rd for f in frames) / len(frames))
        print(f"round: incise run {run_wall:.2f} s in all; Python {python_wall[-1] * 1e3:.2f} ms a frame",
              file=sys.stderr)
    state = sim.save_state()
    restores = []
    for _ in range(args.rounds * 3):
        started = time.perf_counter()
        sim.restore(state)
        restores.append(time.perf_counter() - started)
    started = time.perf_counter()
    state = sim.save_state()
    save_ms = 1e3 * (time.perf_counter() - started)

median = statistics.median
out = {
    "tets": frames[-1].tets,
    "frames": args.frames,
    "incise_run_ms_per_frame": 1e3 * median(run_per_frame),
    "python_ms_per_frame": 1e3 * median(python_per_frame),
    "python_wall_ms_per_frame": 1e3 * median(python_wall),
    "save_state_ms": save_ms,
    "state_bytes": len(state),
    "restore_ms_median": 1e3 * median(restores),
    "restore_ms_min": 1e3 * min(restores),
}
out["python_over_run"] = out["python_wall_ms_per_frame"] / out["incise_run_ms_per_frame"]
print(json.dumps(out, indent=2))
