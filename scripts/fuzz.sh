#!/usr/bin/env bash
# Long fuzz runs: builds the libFuzzer binaries (the `fuzz` preset: clang, ASan, UBSan) and
# runs every target (or those named) for SECONDS each, one after another, from a working
# corpus in build/fuzz/corpus/<target> seeded with fuzz/corpus/<target> (and the data files
# of that format). Prints one line per target: executions, corpus size, findings, and inputs
# saved. Findings are what libFuzzer's fork mode counts: the fuzzed process crashed, ran out
# of memory or hung. Saved inputs (crash-*, leak-*, timeout-*, oom-*, left in
# build/fuzz/findings/<target>/) also include deaths inside the child processes incise reads
# DICOM, MetaImage and TetGen input in (the child inherits libFuzzer's handlers, which save
# the input), which incise contains and reports as an error; replay one with the ci build's
# fuzz_replay to tell them apart. Minimise a real finding with -minimize_crash=1, fix it, and
# add it to fuzz/corpus/<target>/ (replayed by CTest).
# Usage: bash scripts/fuzz.sh SECONDS [TARGET...]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
seconds=${1:?usage: bash scripts/fuzz.sh SECONDS [TARGET...]}
shift
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=(mesh_msh mesh_vtk mesh_vtu mesh_medit mesh_tetgen mesh_obj mesh_stl mesh_ply scene
           plan blade_path session checkpoint checkpoint_state metaimage dicom igtl)
fi
cmake --preset fuzz >/dev/null
cmake --build --preset fuzz
data=$(cd "$root/.." && pwd)/shared/data
declare -A extension=([mesh_msh]=msh [mesh_vtk]=vtk [mesh_vtu]=vtu [mesh_medit]=mesh
                      [mesh_tetgen]=node [mesh_obj]=obj [mesh_stl]=stl [mesh_ply]=ply)
printf '| target | seconds | executions | corpus after | findings (oom / timeout / crash) | inputs saved |\n|---|---|---|---|---|---|\n'
for target in "${targets[@]}"; do
  binary=build/fuzz/fuzz/fuzz_$target
  [ -x "$binary" ] || { echo "no fuzz target $target (built without its library?)" >&2; continue; }
  corpus=build/fuzz/corpus/$target
  findings=build/fuzz/findings/$target
  mkdir -p "$corpus" "$findings"
  cp -n fuzz/corpus/"$target"/* "$corpus"/ 2>/dev/null || true
  if [ -n "${extension[$target]:-}" ] && [ -d "$data" ]; then
    find "$data" -name "*.${extension[$target]}" -size -2M -exec cp -n {} "$corpus"/ \; || true
  fi
  pydicom=/usr/lib/python3/dist-packages/pydicom/data/test_files
  if [ "$target" = dicom ] && [ -d "$pydicom" ]; then
    find "$pydicom" -name '*.dcm' -size -2M -exec cp -n {} "$corpus"/ \; || true
  fi
  log=$findings/run.log
  # -fork runs inputs in a child: a finding is saved and the run goes on to the next one.
  (cd "$findings" && "$root/$binary" -max_total_time="$seconds" -rss_limit_mb=2048 \
    -malloc_limit_mb=1024 -timeout=10 -print_final_stats=1 -fork=1 -ignore_crashes=1 \
    -ignore_timeouts=1 -ignore_ooms=1 "$root/$corpus" >"run.log" 2>&1) || true
  # Fork mode reports "#RUNS: cov: ... oom/timeout/crash: O/T/C ..." as it goes.
  runs=$(grep -oE '^#[0-9]+:' "$log" | tail -1 | tr -d '#:' || true)
  counts=$(grep -oE 'oom/timeout/crash: [0-9]+/[0-9]+/[0-9]+' "$log" | tail -1 | cut -d' ' -f2 || true)
  saved=$(find "$findings" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'leak-*' \
          -o -name 'timeout-*' -o -name 'oom-*' \) | wc -l)
  printf '| `%s` | %s | %s | %s | %s | %s |\n' "$target" "$seconds" "${runs:-?}" \
    "$(find "$corpus" -type f | wc -l)" "${counts:-?}" "$saved"
done
