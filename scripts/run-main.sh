#!/usr/bin/env bash
# The main job: installs dependencies, builds incise (Release) and runs it on real meshes.
# Usage (as root on Debian 12, from anywhere): bash scripts/run-main.sh [OUTPUT_DIR]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
bash scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release --target incise
out=${1:-"$root/out/main"}
mkdir -p "$out"
incise="$root/build/release/apps/incise"
data="$root/../shared/data"

echo "== incise run: the default scene (the seed's Fig. 10: a scalpel cuts the 576-tet block, the wound opens)"
"$incise" run --out "$out/default" --report "$out/default-report.json" \
  --render "$out/default/pictures" --render-every 10
echo "   pictures of the cut: $out/default/pictures/frame_000150.png (offscreen OpenGL)"
echo "== incise generate box (the seed's 4 x 6 x 4-cell block, 576 tetrahedra)"
"$incise" generate box --cells 4 6 4 --size 0.04 0.06 0.04 --tets-per-cell 6 -o "$out/block.vtu"
"$incise" info "$out/block.vtu"
if [ -d "$data" ]; then
  echo "== incise info on the SOFA liver"
  "$incise" info "$data/sofa/liver.msh"
  echo "== incise mesh: tetrahedralise the SOFA liver surface (largest shell)"
  "$incise" mesh "$data/sofa/liver.vtk" --largest-shell --max-volume 50 -o "$out/liver.vtu"
  "$incise" info "$out/liver.vtu"
else
  echo "(../shared/data not found: skipped the real-mesh part)"
fi
echo "== outputs (open the .vtu files in ParaView; cut by hand with: build/release/apps/incise view): $out"
ls -l "$out"
