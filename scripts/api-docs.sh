#!/usr/bin/env bash
# Builds the C++ API reference (Doxygen) from include/incise into build/api-docs/html, and fails
# when an entity is undocumented, or a comment does not parse, in the headers users include
# first (engine, mesh, io, scene), the cutters' (cut, xfem), viewing's (view), the solvers'
# (solve), the models' (physics), planning's or the core's. The other headers' warnings (render,
# igtl, haptics, meshing, imaging, batch) are counted, not fatal.
# Usage: bash scripts/api-docs.sh   (needs doxygen: scripts/install-deps.sh installs it)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
mkdir -p build/api-docs
rm -f build/api-docs/warnings.txt
doxygen docs/api/Doxyfile
warnings=build/api-docs/warnings.txt
first='include/incise/(engine|mesh|io|scene|cut|xfem|view|solve|physics|planning|core)/'
others=$(grep -Ec "^$root/include/incise/" "$warnings" || true)
fatal=$(grep -E "^$root/$first" "$warnings" || true)
echo "API reference: build/api-docs/html/index.html ($others warnings in all headers)"
if [[ -n "$fatal" ]]; then
  echo "undocumented or malformed in the headers users include first:" >&2
  echo "$fatal" >&2
  exit 1
fi
