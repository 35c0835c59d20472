#!/usr/bin/python3
"""Side-by-side stage times of two strata builds (say the previous commit and this one).

Each (scene, method) is rendered by both binaries in turn, --rounds times, so that both see the
same machine load; the table gives the median stage times, per triangle and per fragment, and
the ratio old / new. Images of both builds are compared byte for byte.

  scripts/compare-stages.py OLD/strata NEW/strata --scenes horse.ply,builtin:spheres:32 \\
      --methods opaque,cells,abuffer,embree --size 1024x1024 --frames 5

or one build under two settings (--old-args / --new-args), say the two forms of the tile kernels:

  scripts/compare-stages.py build/strata build/strata --scenes horse.ply --methods opaque,ppll \\
      --args="--k 64" --old-args="--tile-kernels group" --new-args="--tile-kernels serial"
"""
import argparse
import filecmp
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile

# The method's tile stages (its per-fragment work).
FINE = ("raster", "raster+resolve", "composite", "trace", "peel", "bounds", "histogram", "buckets")


def render(binary, scene, method, args, extra, out_dir, tag):
    stats = os.path.join(out_dir, f"{tag}.json")
    image = os.path.join(out_dir, f"{tag}.png")
    cmd = [binary, "render", scene, "-m", method, "-s", args.size, "--frames", str(args.frames),
           "--stats", stats, "-o", image] + shlex.split(args.args) + shlex.split(extra)
    done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        sys.exit(f"compare-stages: {' '.join(cmd)} failed: {done.stderr.strip()}")
    with open(stats) as f:
        return json.load(f), image


def stage_groups(st):
    ms = st["stage_ms"]
    front = ms.get("transform", 0.0) + ms.get("setup", 0.0)
    fine = sum(ms.get(k, 0.0) for k in FINE)
    return {"front": front, "bin": ms.get("bin", 0.0), "fine": fine,
            "frame": st["frame_ms"]["median"]}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("--scenes", required=True, help="comma-separated scenes")
    p.add_argument("--methods", default="opaque,cells,abuffer,embree")
    p.add_argument("--size", default="1024x1024")
    p.add_argument("--frames", type=int, default=5)
    p.add_argument("--rounds", type=int, default=2, help="alternating runs of each build")
    p.add_argument("--args", default="", help="more render options for both runs")
    p.add_argument("--old-args", default="", help="render options for the old run only")
    p.add_argument("--new-args", default="", help="render options for the new run only")
    args = p.parse_args()
    print(f"| scene | method | px/tri | front end ns/tri old -> new | bin ns/tri old -> new | "
          f"fine ns/frag old -> new | frame ms old -> new (old/new) | same image |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes.split(","):
            for method in args.methods.split(","):
                runs = {"old": [], "new": []}
                images = {}
                for r in range(args.rounds):
                    for which in ("old", "new"):
                        st, img = render(getattr(args, which), scene, method, args,
                                         getattr(args, f"{which}_args"), tmp, f"{which}-{r}")
                        runs[which].append(stage_groups(st))
                        images[which] = img
                        tris = max(st["triangles"], 1)
                        frags = max(st["fragments"], 1)
                med = {w: {k: statistics.median(x[k] for x in runs[w]) for k in runs[w][0]}
                       for w in runs}
                same = filecmp.cmp(images["old"], images["new"], shallow=False)

                def pair(key, scale, fmt="%.1f"):
                    a, b = med["old"][key] * scale, med["new"][key] * scale
                    if a == 0 and b == 0:
                        return "-"
                    return (fmt % a) + " -> " + (fmt % b) + (f" ({a / b:.2f}x)" if b else "")

                name = os.path.basename(scene)
                print(f"| {name} | {method} | {frags / tris:.1f} | {pair('front', 1e6 / tris)} | "
                      f"{pair('bin', 1e6 / tris)} | {pair('fine', 1e6 / frags, '%.2f')} | "
                      f"{pair('frame', 1.0)} | {'yes' if same else 'no'} |", flush=True)


if __name__ == "__main__":
    main()
