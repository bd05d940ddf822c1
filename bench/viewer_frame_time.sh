#!/usr/bin/env bash
# The viewer's frame time (physics + drawing + panels), under Xvfb on llvmpipe: the default
# scene and a 50k-tet FEM body, each played for a fixed number of frames.
# Usage: bash bench/viewer_frame_time.sh [BUILD_DIR]   (default build/release)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
incise="${1:-$root/build/release}/apps/incise"
xvfb=(xvfb-run -a -s "-screen 0 1280x1024x24")
echo "== default scene (576 tets, mass-spring, hierarchical RK4), 150 frames, 1280x800"
"${xvfb[@]}" "$incise" view --exit-after 150 2>&1 | tail -1
echo "== 50k-tet corotational FEM box, backward Euler, 60 frames, 1280x800"
"${xvfb[@]}" "$incise" view "$root/bench/viewer_fem_50k.json" --exit-after 60 2>&1 | tail -1
echo "== the same body with the two-level preconditioner"
"${xvfb[@]}" "$incise" view "$root/bench/viewer_fem_50k_two_level.json" --exit-after 60 2>&1 | tail -1
echo "== the same body solved to a real-time tolerance (CG to 1e-3; bench/solver_tolerance.py)"
"${xvfb[@]}" "$incise" view "$root/bench/viewer_fem_50k_realtime.json" --exit-after 60 2>&1 | tail -1
echo "== default scene again, the physics paced to the scene's frame time as when a user watches"
"${xvfb[@]}" "$incise" view --exit-after 150 --paced 2>&1 | tail -1
