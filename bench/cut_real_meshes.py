#!/usr/bin/env python3
"""Full cuts of the real meshes in ../shared/data, sampled in 1 (one move), 24, 240 and 2,400
poses: tets out, pieces (by faces and by vertices), cd + gc per pose (mean and worst), through
`incise cut`. The blade: vertical, from below to above the body, swept along x across the whole
body at 0.513 of the y-extent (the plane of the issue 'Cut real anatomy right').

usage: bench/cut_real_meshes.py [--incise build/release/apps/incise] [--poses 1,24,240,2400]
                                [--repeats 3]

Each cut runs --repeats times (the same cut every time); mean and worst pose are the median of
the runs, so one pose that the operating system interrupts does not stand for the cutter.
"""
import argparse
import json
import os
import statistics
import subprocess
import tempfile

MESHES = ["sofa/liver.msh", "sofa-mor/liverTinyMesh.vtu", "sofa-mor/liverVeryCOARSE.vtu",
          "sofa-mor/liverCoarse.vtu", "sofa-mor/liverSemiFine.vtu", "pbd/armadillo_4k.ele",
          "sofa/cylinder.msh", "sofa/cube_low_res.msh", "libigl/octopus-low.mesh"]


def write_full_cut(blade, info, n):
    """Writes the full cut of a body (its `incise info --json`) in n poses to `blade`; returns
    the plane's y."""
    low, high = info["bounding_box"]["min"], info["bounding_box"]["max"]
    size = [h - l for l, h in zip(low, high)]
    y = low[1] + 0.513 * size[1]
    with open(blade, "w") as f:
        f.write("t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n")
        for i in range(n + 1):
            x = low[0] - 0.1 * size[0] + 1.2 * size[0] * i / n
            f.write(f"{i * 0.01},{x},{y},{low[2] - 0.1 * size[2]},{x},{y},"
                    f"{high[2] + 0.1 * size[2]}\n")
    return y


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    parser = argparse.ArgumentParser()
    parser.add_argument("--incise", default=os.path.join(root, "build/release/apps/incise"))
    parser.add_argument("--data", default=os.path.join(root, "../shared/data"))
    parser.add_argument("--poses", default="1,24,240,2400")
    parser.add_argument("--extra", default="", help="extra flags for incise cut")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    counts = [int(n) for n in args.poses.split(",")]
    print("| mesh | tets in | " + " | ".join(f"{n} poses: tets / pieces / mean / max ms" for n in counts) + " |")
    print("|---|---|" + "---|" * len(counts))
    with tempfile.TemporaryDirectory() as scratch:
        for mesh in MESHES:
            path = os.path.join(args.data, mesh)
            info = json.loads(subprocess.check_output([args.incise, "info", path, "--json"]))
            cells = []
            for n in counts:
                blade = os.path.join(scratch, "blade.csv")
                write_full_cut(blade, info, n)
                report = os.path.join(scratch, "report.json")
                means, worst = [], []
                for _ in range(max(1, args.repeats)):
                    subprocess.run([args.incise, "cut", path, "--blade", blade, "-o",
                                    os.path.join(scratch, "out.vtu"), "--report", report]
                                   + args.extra.split(), check=False, capture_output=True)
                    r = json.load(open(report))
                    means.append((r["cd"] + r["gc"]) / n)
                    worst.append(r["max_pose_ms"])
                mean = statistics.median(means)
                cells.append(f"{r['tets_out']} / {r['components']}"
                             f"{'' if r['pieces_by_vertices'] == r['components'] else '(' + str(r['pieces_by_vertices']) + ')'}"
                             f"{'' if r['valid'] and r['invalid_frames'] == 0 else ' INVALID'}"
                             f" / {mean:.2f} / {statistics.median(worst):.1f}")
            print(f"| `{mesh}` | {info['tets']} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
