#!/usr/bin/env bash
# Installs every Debian package incise needs to build, test and benchmark.
# Idempotent: packages already present are skipped; `apt-get update` runs once, and only
# when something is missing. Run as root (or with sudo available) on Debian 12.
set -euo pipefail

packages=(
  # toolchain
  build-essential clang cmake ninja-build pkg-config clang-format
  # core numerics and parallel loops; sparse direct solves (CHOLMOD) with an optimised BLAS
  libeigen3-dev libtbb-dev libsuitesparse-dev libopenblas0-pthread
  # planning: L-BFGS minimisation; CT volumes (MetaImage, DICOM through GDCM) read by ITK;
  # pydicom writes the DICOM series the imaging tests read
  liblbfgs-dev libinsighttoolkit5-dev python3-pydicom
  # readers incise did not write, opening what it writes in the tests: VTK's own (what
  # ParaView reads with) and meshio
  python3-vtk9 python3-meshio python3-numpy
  # robust geometry (CGAL is header-only in 5.x; GMP/MPFR back its exact kernel)
  libcgal-dev libgmp-dev libmpfr-dev libboost-dev
  # tetrahedral meshing (TetGen's library)
  libtet1.5-dev
  # I/O: XML for .vtu, zlib for compressed VTK data
  libpugixml-dev zlib1g-dev
  # application plumbing
  nlohmann-json3-dev libcli11-dev libspdlog-dev libfmt-dev
  # tests and benchmarks; the API reference (scripts/api-docs.sh)
  libgtest-dev libgmock-dev libbenchmark-dev doxygen
  # the FEM peer in bench/ (Bullet's deformable solver), and the algebraic multigrid peers of
  # CG's preconditioners (hypre's BoomerAMG and PETSc's GAMG, bench/amg_compare.cpp)
  libbullet-dev libhypre-dev libpetsc-real-dev
  # pictures: PNG files, OpenGL 3.3 offscreen through EGL on Mesa (llvmpipe without a GPU)
  libpng-dev libegl-dev libopengl-dev libegl-mesa0 libgl1-mesa-dri
  # labels on pictures: stb_easy_font (a built-in font, no font file)
  libstb-dev
  # the interactive viewer: a GLFW window with Dear ImGui panels; Xvfb runs it in CI and
  # xdotool moves its mouse there
  libglfw3-dev libimgui-dev xvfb xauth xdotool
  # the Python module (import incise): pybind11 on Debian's Python 3 with numpy; pytest runs
  # its tests; pandas, Dask's distributed scheduler, matplotlib and scipy serve the sweep and
  # the examples
  pybind11-dev python3-dev python3-numpy python3-pytest python3-pandas python3-dask
  python3-distributed python3-matplotlib python3-scipy
  # mypy checks the package and the examples against its type stubs
  mypy
  # the device protocol (incise serve / incise device): OpenIGTLink, as 3D Slicer speaks it
  libopenigtlink-dev
)
# Video (incise run --video) uses the ffmpeg program when it is on PATH; it is not installed
# here (about 90 packages): apt-get install ffmpeg.

missing=()
for package in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$package")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  sudo_cmd=(sudo)
fi
echo "install-deps: installing ${missing[*]}"
"${sudo_cmd[@]}" apt-get update -qq
DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
