#!/bin/sh
# strata's check on a GPU machine, from the relocatable bundle of scripts/gpu-bundle.sh: lists
# the OpenCL devices, runs the exact image tests (every method against the embree reference) on
# the first GPU, then the paper-table2 and paper-table1 benches, per-stage times on the horse and
# the spheres, and a moving camera on the horse (cells with and without its order made ahead, and
# the baselines), all within about 7 minutes (the image tests include the path without 64-bit
# atomics, Atomics32.*, beside the 64-bit one); without a GPU device it stops after the listing.
#   gpu-check.sh BUNDLE.tar.xz OUT [--quick | --no-bench]
# OUT gets summary.txt, info.txt and details.tar.gz (test log and JSON, bench results, images of
# failed tests). --quick: a short run for trying the bundle on a CPU device (PoCL); --no-bench:
# everything but the paper-table benches (about 3 minutes on an H200).
# The OpenCL driver is the machine's libnvidia-opencl.so.1 (found through ldconfig,
# /usr/local/nvidia or /usr/lib*); without one, the ICDs of $OCL_ICD_VENDORS or
# /etc/OpenCL/vendors. Each step has its own time limit; a failed step does not stop the next.
set -u
if [ $# -lt 2 ]; then
  sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
BUNDLE=$1
OUT=$2
QUICK=${3:-}
ROOT=/tmp/strata-bundle
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
DETAILS=$OUT/details
mkdir -p "$DETAILS"
SUMMARY=$OUT/summary.txt
: >"$SUMMARY"
say() { echo "$*" | tee -a "$SUMMARY"; }

rm -rf "$ROOT"
tar -xJf "$BUNDLE" -C /tmp || { say "cannot unpack $BUNDLE"; exit 1; }
say "strata gpu-check: bundle of commit $(cat $ROOT/COMMIT), $(date -u +%Y-%m-%dT%H:%M:%SZ)"

LD_LIBRARY_PATH=$ROOT/lib
ldconfig -p 2>/dev/null | grep -q 'libstdc++.so.6 ' || LD_LIBRARY_PATH=$LD_LIBRARY_PATH:$ROOT/lib/fallback
export LD_LIBRARY_PATH
export XDG_CACHE_HOME=$ROOT/cache

nvidia=$(ldconfig -p 2>/dev/null | awk '/libnvidia-opencl.so.1 /{print $NF; exit}')
if [ -z "$nvidia" ]; then
  for d in /usr/local/nvidia/lib64 /usr/local/nvidia/lib /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib; do
    [ -e "$d/libnvidia-opencl.so.1" ] && { nvidia=$d/libnvidia-opencl.so.1; break; }
  done
fi
if [ -n "$nvidia" ]; then
  mkdir -p "$ROOT/icd"
  echo "$nvidia" >"$ROOT/icd/nvidia.icd"
  export OCL_ICD_VENDORS=$ROOT/icd
  say "OpenCL driver: $nvidia"
elif [ -n "${OCL_ICD_VENDORS:-}" ]; then
  say "OpenCL drivers: OCL_ICD_VENDORS=$OCL_ICD_VENDORS"
else
  say "OpenCL drivers: /etc/OpenCL/vendors ($(ls /etc/OpenCL/vendors 2>/dev/null | tr '\n' ' '))"
fi

STRATA=$ROOT/bin/strata
if command -v nvidia-smi >/dev/null; then
  nvidia-smi -L
  nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv
fi >"$OUT/info.txt" 2>&1
"$STRATA" info >>"$OUT/info.txt" 2>&1
say "strata info: exit $?"
cat "$OUT/info.txt" | head -30 >>"$SUMMARY"
# Without a GPU the rest would only measure the CPU: say what the machine has, and stop early so
# that a second try fits in the same lease.
if [ "$QUICK" != --quick ] && ! grep -qE ', GPU$' "$OUT/info.txt"; then
  {
    echo "no OpenCL GPU device: the driver files this machine has"
    ls -l /usr/local/nvidia/lib64 /usr/local/nvidia/lib 2>&1 | grep -i -e opencl -e cuda -e total
    ldconfig -p 2>/dev/null | grep -i -e opencl -e libcuda
    ls -l /etc/OpenCL/vendors 2>&1
    find / -xdev -name 'libnvidia-opencl*' 2>/dev/null | head
  } >>"$SUMMARY" 2>&1
  exit 3
fi

# The exact image tests: every method's image against embree's, fragment counts, raster rules.
FILTER='Models/*:Scenes/*:SharedAndMassive/*:TranslucencyReference.*:EmbreeTextured.*:TexturedScene.*:Cells.*:BucketPeeling.*:Peeling.*:FixedBudget.*:PpllDeepPixels.*:RasterRules.*:MovingCamera.*:CellOrder.DeviceMasksAndPairsGiveTheHostOrder:Picking.*:TileKernels.*:Atomics32.*'
TEST_LIMIT=150
if [ "$QUICK" = --quick ]; then
  FILTER='RasterRules.*:TranslucencyReference.*:Models/ReferenceImages.*/0'
  TEST_LIMIT=600
fi
start=$(date +%s)
timeout "$TEST_LIMIT" "$ROOT/bin/strata_tests" --gtest_filter="$FILTER" \
  --gtest_output="json:$DETAILS/tests.json" >"$DETAILS/tests.log" 2>&1
rc=$?
say "image tests: exit $rc in $(($(date +%s) - start)) s$([ $rc = 124 ] && echo ' (time limit)'): $(grep -E '^\[  (PASSED|FAILED) ' "$DETAILS/tests.log" | tr '\n' ' ')"
grep -E '^\[  FAILED  \]' "$DETAILS/tests.log" | head -20 | tee -a "$SUMMARY"
[ -d "$ROOT/test-output/images" ] && cp -r "$ROOT/test-output/images" "$DETAILS/failed-images"

bench() {
  suite=$1 limit=$2
  start=$(date +%s)
  timeout "$limit" "$STRATA" bench --suite "$suite" --models "$ROOT/models" --out "$DETAILS/$suite" \
    >"$DETAILS/$suite.log" 2>&1
  rc=$?
  say "bench $suite: exit $rc in $(($(date +%s) - start)) s$([ $rc = 124 ] && echo ' (time limit)')"
  [ -f "$DETAILS/$suite/results.md" ] && cat "$DETAILS/$suite/results.md" >>"$SUMMARY"
}
if [ "$QUICK" = --quick ]; then
  bench smoke 600
elif [ "$QUICK" != --no-bench ]; then
  bench paper-table2 60
  bench paper-table1 70
fi

# Per-stage times of the shared front end and the methods (stage_ms in the stats JSON).
stages() {
  tag=$1 scene=$2
  shift 2
  timeout 30 "$STRATA" render "$scene" -s 1024x1024 --frames 5 -m opaque,cells,abuffer,embree --k 64 \
    --stats "$DETAILS/stages-$tag.json" "$@" >"$DETAILS/stages-$tag.log" 2>&1
  say "stages $tag: exit $? $(grep -E '^(cells|opaque|abuffer|embree) ' "$DETAILS/stages-$tag.log" | tr -s ' ' | tr '\n' ';')"
  # Where each method's frame goes, kernel by kernel (ms per frame, launches).
  python3 - "$DETAILS/stages-$tag.json" <<'PY' >>"$SUMMARY" 2>&1
import json, sys
d = json.load(open(sys.argv[1]))
for m in d if isinstance(d, list) else d.get("methods", [d]):
    k = m.get("kernel_ms", {})
    top = sorted(k.items(), key=lambda kv: -kv[1]["ms"])[:8]
    print("  %s: %s" % (m.get("method"), ", ".join(
        "%s %.3f/%d" % (n, v["ms"], v["launches"]) for n, v in top)))
PY
}
if [ "$QUICK" != --quick ]; then
  stages horse "$ROOT/models/horse.ply"
  stages spheres32 builtin:spheres:32
  stages spheres96 builtin:spheres:96
fi

# A moving camera on the horse: cells with the next view ordered during the device's frame or
# not, each frame ordering its own view or reusing one (the default), then the baselines (their
# median and mean frames go to the summary, the stats to details/).
moving() {
  tag=$1
  shift
  timeout 25 "$STRATA" render "$ROOT/models/horse.ply" -s 1024x1024 --frames 20 --orbit 1 \
    --stats "$DETAILS/moving-$tag.json" -o "$DETAILS/moving-$tag.png" "$@" >"$DETAILS/moving-$tag.log" 2>&1
  say "moving horse, $tag: exit $? $(grep -E '^(cells|opaque|abuffer|ppll|embree) ' "$DETAILS/moving-$tag.log" | tr -s ' ' | tr '\n' ';')"
}
if [ "$QUICK" != --quick ]; then
  moving cells-ahead-off -m cells --order-ahead off --order-masks host --order-reuse 0
  moving cells-ahead-on -m cells --order-ahead on --order-masks host --order-reuse 0
  moving cells-reuse-3 -m cells --order-ahead on --order-masks host --order-reuse 3
  moving cells-reuse-8 -m cells --order-ahead on --order-masks host --order-reuse 8
  moving cells-masks-device-ahead-off -m cells --order-ahead off --order-masks device --order-reuse 0
  moving cells-masks-device-ahead-on -m cells --order-ahead on --order-masks device --order-reuse 0
  moving cells-tile-segments-on -m cells --order-ahead off --order-masks host --tile-segments on
  moving baselines -m opaque,abuffer,ppll,embree --k 64
fi

# The order alone per view, its steps, and the host's threads (this machine's CPU orders for
# the GPU): pixel masks on the host, then on the device (the same fingerprint).
if [ "$QUICK" != --quick ] && [ -x "$ROOT/bin/strata_order_bench" ]; then
  say "host: $(nproc) cores seen, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
  # Masks on the host, then on the device (the same fingerprint), with the tile segments (a still
  # camera's order) and without (a moving camera's); the host's also with all the host's threads
  # (the default is at most eight).
  for run in "host" "host --no-segments" "host --threads $(nproc)" "device" \
    "device --no-segments"; do
    tag=$(echo "$run" | tr -d ' -')
    timeout 60 "$ROOT/bin/strata_order_bench" "$ROOT/models/horse.ply" \
      "$ROOT/models/stanford-bunny.obj" --views 30 --masks $run \
      >"$DETAILS/order-$tag.log" 2>&1
    say "order bench, masks on $run: exit $?"
    cat "$DETAILS/order-$tag.log" >>"$SUMMARY"
  done
fi

tar -C "$OUT" -czf "$OUT/details.tar.gz" details && rm -rf "$DETAILS"
say "results: $OUT (summary.txt, info.txt, details.tar.gz)"
