#!/usr/bin/env bash
# Builds the C++ API reference (Doxygen) from include/incise into build/api-docs/html, and fails
# when an entity of a public header is undocumented or a comment there does not parse.
# Usage: bash scripts/api-docs.sh   (needs doxygen: scripts/install-deps.sh installs it)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
mkdir -p build/api-docs
rm -f build/api-docs/warnings.txt
doxygen docs/api/Doxyfile
warnings=build/api-docs/warnings.txt
fatal=$(grep -E "^$root/include/incise/" "$warnings" | sort -u || true)
echo "API reference: build/api-docs/html/index.html"
if [[ -n "$fatal" ]]; then
  echo "undocumented or malformed in the public headers:" >&2
  echo "$fatal" >&2
  exit 1
fi
