#!/bin/sh
# Builds the relocatable bundle that scripts/gpu-check.sh runs on a bare GPU machine (one with an
# OpenCL driver and nothing to install from): strata, its test binary and the order bench built
# without OpenImageIO and MPI (images through stb), every shared library they load except
# glibc's, the OpenCL ICD loader, the shared test models and gpu-check.sh itself, packed with xz.
#   scripts/gpu-bundle.sh [OUTPUT]       (default: gpu-bundle/strata-gpu-bundle.tar.xz)
# The bundle unpacks into /tmp/strata-bundle, where the tests look for their models.
set -eu
cd "$(dirname "$0")/.."
OUTPUT=${1:-gpu-bundle/strata-gpu-bundle.tar.xz}
ROOT=/tmp/strata-bundle
BUILD=build-bundle
LIMIT_MB=60

cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DSTRATA_WITH_OPENIMAGEIO=OFF \
  -DSTRATA_WITH_MPI=OFF -DSTRATA_BUILD_PYTHON=OFF -DSTRATA_BUILD_TESTS=ON \
  -DSTRATA_TEST_MODELS_DIR=$ROOT/models -DSTRATA_TEST_ASSIMP_DIR=$ROOT/assimp \
  -DSTRATA_TEST_OUTPUT=$ROOT/test-output >/dev/null
cmake --build "$BUILD" -j "$(nproc)" --target strata strata_tests strata_order_bench

STAGE_PARENT=$(mktemp -d)
trap 'rm -rf "$STAGE_PARENT"' EXIT INT TERM
STAGE=$STAGE_PARENT/strata-bundle
mkdir -p "$STAGE/bin" "$STAGE/lib" "$STAGE/lib/fallback" "$STAGE/models"
cp "$BUILD/strata" "$BUILD/tests/strata_tests" "$BUILD/strata_order_bench" "$STAGE/bin/"
# Every library the programs load, but glibc's own (the machine's glibc must be used) and the
# C++ runtime, which goes to lib/fallback: the machine's own (newer) one is preferred when it has
# one, since its OpenCL driver may need it.
for lib in $(ldd "$BUILD/strata" "$BUILD/tests/strata_tests" "$BUILD/strata_order_bench" | awk '/=> \//{print $3}' | sort -u); do
  case $(basename "$lib") in
    libc.so.*|libm.so.*|libpthread.so.*|libdl.so.*|librt.so.*|ld-linux*|libresolv.so.*) ;;
    libstdc++.so.*|libgcc_s.so.*) cp -L "$lib" "$STAGE/lib/fallback/" ;;
    *) cp -L "$lib" "$STAGE/lib/" ;;
  esac
done
strip --strip-unneeded "$STAGE"/bin/* "$STAGE"/lib/*.so* "$STAGE"/lib/fallback/* 2>/dev/null || true
cp tests/models/* "$STAGE/models/"
# The glTF files of assimp's test models that the image tests render (Debian's assimp-testmodels).
mkdir -p "$STAGE/assimp"
for d in glTF glTF2; do
  [ -d "/usr/share/assimp/models/$d" ] && cp -r "/usr/share/assimp/models/$d" "$STAGE/assimp/"
done
cp scripts/gpu-check.sh "$STAGE/"
git rev-parse HEAD >"$STAGE/COMMIT" 2>/dev/null || echo unknown >"$STAGE/COMMIT"

mkdir -p "$(dirname "$OUTPUT")"
tar -C "$STAGE_PARENT" -cf - strata-bundle | xz -T0 -9 >"$OUTPUT.tmp"
mv "$OUTPUT.tmp" "$OUTPUT"
size=$(stat -c %s "$OUTPUT")
echo "gpu-bundle.sh: $OUTPUT: $((size / 1048576)) MiB ($(ls "$STAGE/lib" | wc -l) libraries)"
if [ "$size" -gt $((LIMIT_MB * 1048576)) ]; then
  echo "gpu-bundle.sh: the bundle is larger than $LIMIT_MB MiB" >&2
  exit 1
fi
