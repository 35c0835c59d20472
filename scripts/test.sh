#!/bin/sh
# Installs the dependencies, builds strata and its tests, and runs the whole test suite.
set -eu
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTRATA_BUILD_TESTS=ON
cmake --build build -j "$(nproc)"
cd build && ctest --output-on-failure -j 1
