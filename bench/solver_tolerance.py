#!/usr/bin/env python3
"""What a looser CG tolerance costs in accuracy and saves in time: runs a backward-Euler scene
through `incise run` at several tolerances and compares every written frame with a run solved
to 1e-9 (the reference). Prints, per tolerance, the CG iterations per frame (mean, largest), rx
per frame (ms) and the largest distance of any vertex from where the reference put it (m, over
all frames written), next to the largest displacement.

usage: bench/solver_tolerance.py SCENE [--incise build/release/apps/incise] [--frames 60]
                                 [--every 10] [--tolerances 1e-6,1e-5,1e-4,1e-3,1e-2]

The scene must have an implicit integrator with a "solver"; its other settings are kept. The
frames compared are those the ParaView series holds (every --every-th, the first and the last);
a frame whose mesh differs from the reference's (the cut went elsewhere) is reported, not
compared.
"""
import argparse
import json
import math
import os
import re
import struct
import subprocess
import tempfile


def read_points(path):
    """The current positions of a .vtu written by incise (appended raw data, UInt64 headers)."""
    with open(path, "rb") as f:
        data = f.read()
    marker = data.index(b"<AppendedData")
    header = data[:marker].decode()
    match = re.search(r'Name="Points" NumberOfComponents="3" format="appended" offset="(\d+)"',
                      header)
    if not match:
        raise SystemExit(f"{path}: no appended Points array")
    start = data.index(b"_", marker) + 1 + int(match.group(1))
    size = struct.unpack("<Q", data[start:start + 8])[0]
    values = struct.unpack(f"<{size // 8}d", data[start + 8:start + 8 + size])
    return [values[i:i + 3] for i in range(0, len(values), 3)]


def run(incise, scene, tolerance, frames, every, work):
    """Runs the scene at one tolerance; returns (report, {frame: vtu path})."""
    with open(scene) as f:
        description = json.load(f)
    solver = description.get("integrator", {}).get("solver")
    if solver is None:
        raise SystemExit(f"{scene}: no integrator.solver to set a tolerance on")
    solver["tolerance"] = tolerance
    description.setdefault("output", {})["vtu_every"] = every
    name = f"tol_{tolerance:g}"
    path = os.path.join(work, name + ".json")
    with open(path, "w") as f:
        json.dump(description, f)
    out = os.path.join(work, name)
    report = os.path.join(work, name + "_report.json")
    done = subprocess.run([incise, "run", path, "--frames", str(frames), "--out", out,
                           "--report", report], stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        raise SystemExit(f"incise run at tolerance {tolerance:g} failed:\n{done.stderr}")
    with open(report) as f:
        result = json.load(f)
    written = {}
    for entry in sorted(os.listdir(out)):
        match = re.search(r"_(\d{6})\.vtu$", entry)
        if match:
            written[int(match.group(1))] = os.path.join(out, entry)
    return result, written


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene")
    parser.add_argument("--incise", default="build/release/apps/incise")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--every", type=int, default=10)
    parser.add_argument("--tolerances", default="1e-6,1e-5,1e-4,1e-3,1e-2")
    args = parser.parse_args()
    tolerances = [float(t) for t in args.tolerances.split(",")]
    with tempfile.TemporaryDirectory() as work:
        reference, reference_frames = run(args.incise, args.scene, 1e-9, args.frames, args.every,
                                          work)
        print(f"{args.scene}: {args.frames} frames, {reference['tets']} tets at the end, "
              f"largest displacement {1e3 * reference['max_displacement']:.2f} mm")
        print("| CG tolerance | iterations per frame (mean / most) | rx per frame (ms) | "
              "largest deviation from 1e-9 (mm) |")
        print("|---|---|---|---|")
        for tolerance in [1e-9] + tolerances:
            if tolerance == 1e-9:
                result, frames = reference, reference_frames
            else:
                result, frames = run(args.incise, args.scene, tolerance, args.frames, args.every,
                                     work)
            iterations = [f["solver_iterations"] for f in result["per_frame_ms"]]
            deviation = 0.0
            notes = []
            for frame, path in frames.items():
                if frame not in reference_frames:
                    continue
                points = read_points(path)
                expected = read_points(reference_frames[frame])
                if len(points) != len(expected):
                    notes.append(f"frame {frame}: the mesh differs")
                    continue
                deviation = max(deviation,
                                max(math.dist(p, q) for p, q in zip(points, expected)))
            print(f"| {tolerance:g} | {sum(iterations) / len(iterations):.1f} / "
                  f"{max(iterations)} | {result['mean_ms']['rx']:.1f} | {1e3 * deviation:.4f}"
                  f"{' (' + '; '.join(notes) + ')' if notes else ''} |")


if __name__ == "__main__":
    main()
