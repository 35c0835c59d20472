#!/bin/sh
# Installs the dependencies, builds strata, and renders builtin:demo with every method:
# writes demo-<method>.png and prints each method's frame time.
set -eu
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTRATA_BUILD_TESTS=OFF
cmake --build build -j "$(nproc)" --target strata
./build/strata render builtin:demo --method all --size 512x512 --frames 5 -o demo.png
