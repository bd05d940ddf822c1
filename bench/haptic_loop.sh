#!/usr/bin/env bash
# The haptic loop through loopback: incise serve runs the physics while incise device plays a
# blade path at 1 kHz as OpenIGTLink TRANSFORMs and logs the forces that come back. Reports
# the server's haptic period (p50 / p99 / max), its pose-to-force latency, the device's own
# loop period and round trip, for the 576-tet default block and a 48k-tet FEM box.
# Usage: bash bench/haptic_loop.sh [BUILD_DIR]   (default build/release)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
incise="${1:-$root/build/release}/apps/incise"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
printf 't,tip_x,tip_y,tip_z,base_x,base_y,base_z\n0.0,0.0213,-0.012,0.012,0.0213,-0.012,0.06\n2.0,0.0213,0.072,0.012,0.0213,0.072,0.06\n' >"$work/default_path.csv"

play() {  # name scene path
  local name=$1 scene=$2 path=$3
  rm -f "$work/port"
  "$incise" serve $scene --port 0 --port-file "$work/port" --exit-when-idle --max-seconds 120 \
    --out "$work/$name" >"$work/$name.log" 2>&1 &
  local server=$!
  while [ ! -s "$work/port" ]; do sleep 0.1; done
  echo "== $name"
  "$incise" device "$path" --port "$(cat "$work/port")" --log "$work/$name-forces.csv"
  wait "$server"
  python3 - "$work/$name/report.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
h = r["haptic"]
ms = lambda d: "p50 %.3f / p99 %.3f / max %.3f ms" % (1e3 * d["p50"], 1e3 * d["p99"], 1e3 * d["max"])
print("server: %d frames, physics %.1f ms/frame, %d -> %d tets, valid %s, watertight %s" % (
    r["frames"], r["physics_ms_per_frame"], r["tets_start"], r["tets"], r["valid"], r["watertight"]))
print("haptic loop (real-time priority: %s): period %s, %d overruns of %d ticks" % (
    h["realtime_priority"], ms(h["period_s"]), h["overruns"], h["ticks"]))
print("pose-to-force latency in the server: %s; messages dropped: %d" % (
    ms(h["pose_to_force_latency_s"]), r["messages"]["dropped_total"]))
PY
}

play default-block "" "$work/default_path.csv"
play fem-48k "$root/bench/serve_fem_48k.json" "$root/bench/serve_fem_path.csv"
