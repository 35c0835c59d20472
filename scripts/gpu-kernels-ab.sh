#!/bin/sh
# Kernel changes measured side by side on a GPU machine: one strata binary (from the bundle that
# gpu-check.sh unpacked into /tmp/strata-bundle), each scene rendered with the kernels it embeds
# ("new") and with the kernel sources of OLD_KERNELS ("old", read through STRATA_KERNEL_DIR),
# alternating, with per-kernel times. The kernels must take the binary's arguments.
#   gpu-kernels-ab.sh OLD_KERNELS OUT [ROUNDS] [SCENE ...]
# Make OLD_KERNELS here, in an ignored folder that travels (say gpu-bundle/kold):
#   mkdir -p gpu-bundle/kold && for f in $(git ls-tree --name-only REV kernels/); do
#     git show REV:$f >gpu-bundle/kold/$(basename $f); done; cp -n kernels/* gpu-bundle/kold/
# (the last step adds the files the binary builds that REV did not have yet).
# OUT gets ab.txt (the summary) and ab.tar.gz (every run's log and --stats JSON).
set -u
if [ $# -lt 2 ]; then
  sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
OLD=$(cd "$1" && pwd)
OUT=$2
ROUNDS=${3:-1}
shift 2
[ $# -gt 0 ] && shift
SCENES=${*:-models/horse.ply builtin:spheres:32 builtin:spheres:96}
R=/tmp/strata-bundle
[ -x $R/bin/strata ] || { echo "gpu-kernels-ab.sh: run gpu-check.sh first (no $R)" >&2; exit 1; }
export LD_LIBRARY_PATH=$R/lib XDG_CACHE_HOME=$R/cache
[ -d $R/icd ] && export OCL_ICD_VENDORS=$R/icd
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
RUNS=$(mktemp -d)
round=1
while [ $round -le "$ROUNDS" ]; do
  for scene in $SCENES; do
    for v in old new; do
      tag=$(basename "$scene" | tr ':' '_')-$v-$round
      if [ $v = old ]; then export STRATA_KERNEL_DIR=$OLD; else unset STRATA_KERNEL_DIR; fi
      (cd $R && timeout 60 bin/strata render "$scene" -s 1024x1024 --frames 5 \
        -m opaque,cells,abuffer,ppll --k 64 --stats "$RUNS/$tag.json" >"$RUNS/$tag.log" 2>&1)
      echo "$tag: exit $? $(grep -E '^(cells|opaque|abuffer|ppll) ' "$RUNS/$tag.log" |
        awk '{printf "%s %s ms; ", $1, $2}')"
      # The three costliest kernels of each method (ms per frame).
      python3 - "$RUNS/$tag.json" <<'PY'
import json, sys
try:
    d = json.load(open(sys.argv[1]))
except Exception as e:
    sys.exit(0)
for m in d if isinstance(d, list) else [d]:
    k = sorted(m.get("kernel_ms", {}).items(), key=lambda kv: -kv[1]["ms"])[:3]
    print("   %s: %s" % (m["method"], ", ".join("%s %.3f" % (n, v["ms"]) for n, v in k)))
PY
    done
  done
  round=$((round + 1))
done | tee "$OUT/ab.txt"
unset STRATA_KERNEL_DIR
tar -C "$RUNS" -czf "$OUT/ab.tar.gz" . && rm -rf "$RUNS"
