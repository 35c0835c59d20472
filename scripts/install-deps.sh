#!/bin/sh
# Installs every build and test dependency of strata from Debian 12 packages.
set -eu
PACKAGES="cmake g++ make pkg-config git ca-certificates
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers clinfo
  libglm-dev libopenmesh-dev libopenimageio-dev libtinygltf-dev libcli11-dev
  nlohmann-json3-dev libgtest-dev libgmock-dev libbenchmark-dev libembree-dev libtbb-dev assimp-testmodels libstb-dev libxxhash-dev zlib1g-dev
  libopenmpi-dev openmpi-bin
  oclgrind clang libclang-rt-14-dev pybind11-dev python3-dev python3-pybind11 python3-pytest python3-numpy python3-matplotlib
  python3-venv python3-mypy mesa-opencl-icd python3-skimage"
missing=""
for p in $PACKAGES; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -n "$missing" ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing
fi
