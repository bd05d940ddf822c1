#!/usr/bin/env python3
"""incise serve as 3D Slicer and PLUS users meet it: one live session per scene kind
(mass-spring with subdivision cuts, corotational FEM with subdivision cuts, XFEM with an
embedded visual surface) and per OpenIGTLink header version (1 and 2), each driven by the
specification-written device in tests/tools/igtl_spec_client.py.

Each session must: take the device's poses and cut, answer in the device's header version,
send only surfaces that are closed 2-manifolds (counted by the client, independently of
incise), keep its picture closed (its report), and end cleanly when the device leaves.

Usage: serve_live_test.py INCISE_EXECUTABLE SOURCE_DIR
"""

import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tools"))
import igtl_spec_client  # noqa: E402

# The default block's stroke (a vertical blade along y at x = 0.0213), played in 1 s, and the
# skin patch's (5 mm deep along y across it), in 3 s: its 4,500-tet XFEM frames are slower,
# and a loaded machine runs fewer of them while the blade is in the skin.
BLOCK_STROKE = ("t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n"
                "0.0,0.0213,-0.012,0.012,0.0213,-0.012,0.06\n"
                "1.0,0.0213,0.072,0.012,0.0213,0.072,0.06\n")
SKIN_STROKE = ("t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n"
               "0.0,0.0317,-0.006,0.005,0.0317,-0.006,0.03\n"
               "3.0,0.0317,0.046,0.005,0.0317,0.046,0.03\n")


def session(incise, scene, stroke, version, folder):
    """One serve session; returns the list of what went wrong (empty when all held)."""
    problems = []
    path = os.path.join(folder, "path.csv")
    with open(path, "w") as stream:
        stream.write(stroke)
    port_file = os.path.join(folder, "port")
    out = os.path.join(folder, "out")
    arguments = [incise, "serve"] + ([scene] if scene else []) + [
        "--port", "0", "--port-file", port_file, "--exit-when-idle", "--max-seconds", "60",
        "--out", out]
    with open(os.path.join(folder, "serve.log"), "w") as log:
        server = subprocess.Popen(arguments, stdout=log, stderr=subprocess.STDOUT)
    try:
        for _ in range(200):
            if os.path.exists(port_file) and open(port_file).read().strip():
                break
            time.sleep(0.05)
        port = int(open(port_file).read().strip())
        summary = igtl_spec_client.run(path, port, version, rate=500.0, hold=0.5)
        server.wait(timeout=60)
    finally:
        if server.poll() is None:
            server.kill()
    problems += summary["failures"]
    if summary["surfaces"] == 0:
        problems.append("no surface received")
    if summary["forces"] == 0:
        problems.append("no force received")
    if summary["cut_share_max"] < 1.0:
        problems.append("no point of the surface received lies in a wound (CutFace 1)")
    report = json.load(open(os.path.join(out, "report.json")))
    if report["ended"] != "idle (the last device left)":
        problems.append(f"ended: {report['ended']}")
    if report["tets"] <= report["tets_start"]:
        problems.append("nothing was cut")
    if report["messages"]["dropped_total"] != 0:
        problems.append(f"dropped: {report['messages']['dropped']}")
    visual = report.get("visual_surface")
    if not report["valid"]:
        problems.append("the final mesh is not valid")
    if visual is None and not report["watertight"]:
        # (an XFEM mesh's virtual elements overlap by design: its picture is the visual surface)
        problems.append("the final mesh's boundary is not closed")
    if visual is not None and not visual["closed_manifold"]:
        problems.append(f"the visual surface is not closed: {visual}")
    print(f"  {os.path.basename(scene) if scene else 'default scene'}, header version {version}: "
          f"{summary['poses_sent']} poses, {summary['forces']} forces, {summary['surfaces']} "
          f"surfaces ({summary['closed_surfaces']} closed, largest edge use "
          f"{summary['largest_edge_use']}), {report['tets_start']} -> {report['tets']} tets"
          + (f", picture kept {visual['kept_last_picture']} times ({visual['last_failure']})"
             if visual else ""))
    return problems


def main():
    incise, source = sys.argv[1], sys.argv[2]
    scenes = [("", BLOCK_STROKE),
              (os.path.join(source, "scenes", "fem_cut_pull.json"), BLOCK_STROKE),
              (os.path.join(source, "scenes", "xfem_skin.json"), SKIN_STROKE)]
    passed = 0
    failed = 0
    with tempfile.TemporaryDirectory(prefix="incise-serve-live-") as scratch:
        for index, (scene, stroke) in enumerate(scenes):
            for version in (1, 2):
                folder = os.path.join(scratch, f"{index}-v{version}")
                os.makedirs(folder)
                problems = session(incise, scene, stroke, version, folder)
                if problems:
                    # A real-time session on a machine the rest of the suite loads (ctest -j2
                    # on 2 cores) failed once in a full run and never alone: what went wrong is
                    # printed, and the session is played once more; a failure that repeats fails.
                    print("    failed once, played again: " + "; ".join(problems[:5]))
                    print(open(os.path.join(folder, "serve.log")).read()[-2000:])
                    folder = os.path.join(scratch, f"{index}-v{version}-again")
                    os.makedirs(folder)
                    problems = session(incise, scene, stroke, version, folder)
                if problems:
                    failed += 1
                    print("    FAILED: " + "; ".join(problems[:5]))
                    print(open(os.path.join(folder, "serve.log")).read()[-2000:])
                else:
                    passed += 1
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
