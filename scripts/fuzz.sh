#!/bin/sh
# Builds the libFuzzer targets (clang, ASan, UBSan) in build-fuzz/ and runs each for SECONDS
# (default 30) from its seed corpus; fails on the first crash, leak, hang or broken message rule.
#   scripts/fuzz.sh [-j JOBS] [-o FOLDER] [SECONDS [TARGET...]]
# JOBS targets run at once (default 1). Crash inputs are kept in FOLDER/crashes (default
# build-fuzz/), the grown corpora in FOLDER/corpus; each target's log in FOLDER/logs/TARGET.log.
# The build folder is $STRATA_FUZZ_BUILD (default build-fuzz). Needs the packages of
# scripts/install-deps.sh (clang, libclang-rt-14-dev).
set -eu
cd "$(dirname "$0")/.."
BUILD=${STRATA_FUZZ_BUILD:-build-fuzz}
JOBS=1
OUT=$BUILD
while [ $# -gt 0 ]; do
  case "$1" in
    -j) JOBS=$2; shift 2 ;;
    -j*) JOBS=${1#-j}; shift ;;
    -o) OUT=$2; shift 2 ;;
    -h|--help) sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "fuzz.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) break ;;
  esac
done
SECONDS_EACH=${1:-30}
[ $# -gt 0 ] && shift
ALL="fuzz_obj fuzz_ply fuzz_off fuzz_stl fuzz_gltf fuzz_glb fuzz_gltf1 fuzz_octree_scene
  fuzz_texture fuzz_cell_cache fuzz_octree_cache fuzz_program_cache"
TARGETS=${*:-$ALL}

command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ not found (scripts/install-deps.sh)" >&2; exit 1; }
mkdir -p "$BUILD"
CXX=clang++ cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTRATA_BUILD_FUZZERS=ON \
  -DSTRATA_BUILD_TESTS=OFF -DSTRATA_BUILD_PYTHON=OFF >"$BUILD/configure.log"
cmake --build "$BUILD" --target strata_fuzzers -j "$(nproc)" >"$BUILD/build.log" 2>&1 ||
  { tail -30 "$BUILD/build.log" >&2; echo "fuzz.sh: building the fuzzers failed" >&2; exit 1; }

mkdir -p "$OUT/corpus" "$OUT/crashes" "$OUT/logs" "$OUT/seeds"
/usr/bin/python3 fuzz/make_corpus.py "$OUT/seeds" >/dev/null
"$BUILD/fuzz/strata_fuzz_cache_seeds" "$OUT/seeds" >/dev/null

# The sanitizers stop at the first error; libFuzzer reports leaks at exit of each input.
export ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=0
export LSAN_OPTIONS="suppressions=$(pwd)/fuzz/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1

run_one() {
  t=$1
  mkdir -p "$OUT/corpus/$t"
  # -timeout: any one input taking this long is a hang; -rss_limit_mb: a small file must not
  # make strata take gigabytes; -malloc_limit_mb above the largest texture a loader may reserve
  # (4 GiB of texels, filled only as its rows decode), which is not taking it.
  # fuzz/regressions/TARGET: inputs that once failed, run first with the seeds.
  mkdir -p "$OUT/seeds/$t"
  [ -d "fuzz/regressions/$t" ] && cp fuzz/regressions/"$t"/* "$OUT/seeds/$t/"
  if "$BUILD/fuzz/$t" "$OUT/corpus/$t" "$OUT/seeds/$t" -max_total_time="$SECONDS_EACH" \
      -timeout=25 -rss_limit_mb=3072 -malloc_limit_mb=4608 -max_len=131072 -close_fd_mask=1 -print_final_stats=1 \
      -artifact_prefix="$OUT/crashes/$t-" >"$OUT/logs/$t.log" 2>&1; then
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$OUT/logs/$t.log")
    cov=$(grep -o 'cov: [0-9]*' "$OUT/logs/$t.log" | tail -1)
    echo "fuzz.sh: $t: ok, $execs inputs in ${SECONDS_EACH}s, $cov"
  else
    echo "fuzz.sh: $t: FAILED (log $OUT/logs/$t.log):" >&2
    grep -E 'ERROR|strata-fuzz|SUMMARY|Test unit written|==[0-9]+==' "$OUT/logs/$t.log" | head -20 >&2
    return 1
  fi
}

status=0
running=0
pids=""
for t in $TARGETS; do
  [ -x "$BUILD/fuzz/$t" ] || { echo "fuzz.sh: unknown target $t" >&2; exit 2; }
  run_one "$t" &
  pids="$pids $!"
  running=$((running + 1))
  if [ "$running" -ge "$JOBS" ]; then
    for p in $pids; do wait "$p" || status=1; done
    pids=""
    running=0
  fi
done
for p in $pids; do wait "$p" || status=1; done
exit $status
