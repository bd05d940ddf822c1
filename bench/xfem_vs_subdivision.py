#!/usr/bin/env python3
"""The same full cut by both cutters on the real meshes in ../shared/data: degrees of freedom
added, elements, pieces, time (cd + gc). The blade: vertical, from below to above the body,
swept along x across it at 0.513 of the y-extent in 24 poses (bench/cut_real_meshes.py's).

usage: bench/xfem_vs_subdivision.py [--incise build/release/apps/incise]
"""
import argparse
import json
import os
import subprocess
import tempfile

from cut_real_meshes import write_full_cut  # the same blade path

MESHES = ["sofa/liver.msh", "sofa-mor/liverCoarse.vtu", "sofa-mor/liverSemiFine.vtu",
          "pbd/armadillo_4k.ele", "sofa/cylinder.msh", "libigl/octopus-low.mesh"]


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    parser = argparse.ArgumentParser()
    parser.add_argument("--incise", default=os.path.join(root, "build/release/apps/incise"))
    parser.add_argument("--data", default=os.path.join(root, "../shared/data"))
    parser.add_argument("--poses", type=int, default=24)
    args = parser.parse_args()
    print("| mesh | tets in | subdivision: DOFs added / tets out / pieces / cd+gc ms "
          "| XFEM: DOFs added / elements / pieces / min fraction / cd+gc ms | DOF ratio XFEM / subdivision |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as scratch:
        for mesh in MESHES:
            path = os.path.join(args.data, mesh)
            info = json.loads(subprocess.check_output([args.incise, "info", path, "--json"]))
            blade = os.path.join(scratch, "blade.csv")
            write_full_cut(blade, info, args.poses)
            reports = {}
            for method in ("subdivision", "xfem"):
                report = os.path.join(scratch, method + ".json")
                subprocess.run([args.incise, "cut", path, "--blade", blade, "--method", method,
                                "-o", os.path.join(scratch, method + ".vtu"), "--report", report],
                               check=True, capture_output=True)
                reports[method] = json.load(open(report))
            s, x = reports["subdivision"], reports["xfem"]
            s_dofs = 3 * (s["vertices_out"] - s["vertices_in"])
            print(f"| `{mesh}` | {info['tets']} | {s_dofs} / {s['tets_out']} / {s['components']} / "
                  f"{s['cd'] + s['gc']:.1f} | {x['dofs_added']} / {x['tets_out']} / {x['components']} / "
                  f"{x['min_fraction']:.2g} / {x['cd'] + x['gc']:.1f} | "
                  f"{x['dofs_added'] / s_dofs if s_dofs else 0:.2f} |", flush=True)


if __name__ == "__main__":
    main()
