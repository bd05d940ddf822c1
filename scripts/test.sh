#!/usr/bin/env bash
# Installs dependencies, builds with warnings as errors (g++ and clang), runs the whole test
# suite under g++ and again under clang with AddressSanitizer + UBSan (leaving out, by the
# ci-clang test preset's filter, the long numeric tests that run 30-70 times slower there and
# the few that take a minute or more under it; the g++ run has them, and the Python tests,
# since a sanitized module would need the runtime preloaded), replays every fuzz corpus in
# both, runs the threaded parts (parallel element loops, engine snapshots, haptic loop, device
# server) under ThreadSanitizer, checks formatting and the API reference's comments, and
# proves the installed package works with find_package(incise) and the installed Python module
# with import incise.
# Usage (as root on Debian 12): bash scripts/test.sh
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
bash scripts/install-deps.sh

echo "== format check (clang-format)"
mapfile -t sources < <(git ls-files '*.cpp' '*.hpp' 2>/dev/null || find include src apps tests bench -name '*.[ch]pp')
clang-format --dry-run --Werror "${sources[@]}"

echo "== API reference (Doxygen; an undocumented entity in any public header is an error)"
bash scripts/api-docs.sh

echo "== build (CI preset: -Wall -Wextra -Werror)"
cmake --preset ci >/dev/null
cmake --build --preset ci

# Pictures must be made here: offscreen tests fail rather than skip without OpenGL.
export INCISE_REQUIRE_GL=1

echo "== tests"
ctest --preset ci

echo "== the same with clang (-Werror), under AddressSanitizer and UBSan"
cmake --preset ci-clang >/dev/null
cmake --build --preset ci-clang
ctest --preset ci-clang

echo "== the threaded parts with clang under ThreadSanitizer"
cmake --preset tsan >/dev/null
cmake --build --preset tsan
ctest --preset tsan

echo "== installed package: find_package(incise) from a consumer project"
prefix=$(mktemp -d)
trap 'rm -rf "$prefix"' EXIT
cmake --install build/ci --prefix "$prefix/install" >/dev/null
cmake -S tests/consumer -B "$prefix/consumer" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$prefix/install" >/dev/null
cmake --build "$prefix/consumer" >/dev/null
"$prefix/consumer/consumer"
"$prefix/consumer/embed_engine" | tail -1

echo "== installed Python module: import incise from the prefix's dist-packages"
site=$(/usr/bin/python3 -c 'import sys; print("lib/python%d.%d/dist-packages" % sys.version_info[:2])')
(cd "$prefix" && PYTHONPATH="$prefix/install/$site" /usr/bin/python3 -c \
  'import incise; s = incise.Simulation(); s.step(3); print("import incise:", incise.__file__, s.positions.shape)')
echo "all checks passed"
