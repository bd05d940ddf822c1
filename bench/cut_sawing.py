#!/usr/bin/env python3
"""Sawing: an oblique blade sawing back and forth across the middle of a body with tremor,
sinking through it, as in the issue 'Cut real anatomy right'. Per mesh: tets in -> out, pieces
(by faces / by vertices), mean and worst cd + gc per pose, wall time, through `incise cut`.

The path (seeded): pose i of n: x = low + (0.5 + 0.45 sin(0.3 i)) w + N(0, 0.004 w),
y = low + 0.5 d + N(0, 0.004 d) (w, d, h: the body's extent along x, y, z); the blade runs from
(x - 0.1 w, y, s - 0.3 h) to (x + 0.1 w, y + 0.05 d, s + 0.5 h), its depth s sinking from
0.05 h above the top by 0.8 h over the n poses.

usage: bench/cut_sawing.py [--incise build/release/apps/incise] [--poses 200] [--seed 3]
"""
import argparse
import json
import math
import os
import random
import subprocess
import tempfile
import time

MESHES = ["sofa-mor/liverVeryCOARSE.vtu", "sofa/liver.msh", "sofa-mor/liverCoarse.vtu",
          "libigl/octopus-low.mesh"]


def write_sawing(path, info, poses, seed):
    low, high = info["bounding_box"]["min"], info["bounding_box"]["max"]
    w, d, h = (hi - lo for lo, hi in zip(low, high))
    rng = random.Random(seed)
    with open(path, "w") as f:
        f.write("t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n")
        for i in range(poses + 1):
            x = low[0] + (0.5 + 0.45 * math.sin(0.3 * i)) * w + rng.gauss(0.0, 0.004 * w)
            y = low[1] + 0.5 * d + rng.gauss(0.0, 0.004 * d)
            s = high[2] + 0.05 * h - 0.8 * h * i / poses
            f.write(f"{0.01 * i},{x - 0.1 * w},{y},{s - 0.3 * h},"
                    f"{x + 0.1 * w},{y + 0.05 * d},{s + 0.5 * h}\n")


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    parser = argparse.ArgumentParser()
    parser.add_argument("--incise", default=os.path.join(root, "build/release/apps/incise"))
    parser.add_argument("--data", default=os.path.join(root, "../shared/data"))
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    print("| mesh | tets in -> out | pieces (faces / vertices) | mean / worst pose (cd + gc) "
          "| blade vertices / collapsed | wall |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as scratch:
        for mesh in MESHES:
            path = os.path.join(args.data, mesh)
            info = json.loads(subprocess.check_output([args.incise, "info", path, "--json"]))
            blade = os.path.join(scratch, "blade.csv")
            write_sawing(blade, info, args.poses, args.seed)
            report = os.path.join(scratch, "report.json")
            start = time.monotonic()
            subprocess.run([args.incise, "cut", path, "--blade", blade, "-o",
                            os.path.join(scratch, "out.vtu"), "--report", report],
                           check=True, capture_output=True)
            wall = time.monotonic() - start
            r = json.load(open(report))
            mean = (r["cd"] + r["gc"]) / args.poses  # the report gives ms
            print(f"| `{mesh}` | {r['tets_in']:,} -> {r['tets_out']:,} | {r['components']} / "
                  f"{r['pieces_by_vertices']} | {mean:.1f} / {r['max_pose_ms']:.1f} ms | "
                  f"{r['blade_vertices']} / {r.get('blade_points_collapsed', 0)} | {wall:.1f} s |")


if __name__ == "__main__":
    main()
