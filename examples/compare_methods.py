#!/usr/bin/python3
"""Compare strata's methods on the stacked-spheres depth test: frame time against depth
complexity, one line per method, saved as methods-vs-depth.png (matplotlib).

    PYTHONPATH=build/python /usr/bin/python3 examples/compare_methods.py [--size 256]
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

import strata

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--size", type=int, default=256)
parser.add_argument("--depths", default="16,32,48,64")
parser.add_argument("--methods", default="cells,ppll,abuffer,dp,ddp,embree")
parser.add_argument("--out", default="methods-vs-depth.png")
args = parser.parse_args()

device = strata.Device()
depths = [int(d) for d in args.depths.split(",")]
times = {m: [] for m in args.methods.split(",")}
for depth in depths:
    geometry = strata.load(f"builtin:spheres:{depth}")
    for method in times:
        r = strata.Renderer(device, method, frames=3, k=max(depth, 16))
        r.set_geometry(geometry)
        r.render(az=0, el=90, width=args.size, height=args.size, ortho=True)
        times[method].append(r.stats["frame_ms"]["median"])
        print(f"{method:8s} depth {depth:3d}: {times[method][-1]:8.2f} ms, "
              f"{r.stats['fragments']} fragments")

for method, ms in times.items():
    plt.plot(depths, ms, marker="o", label=method)
plt.xlabel("depth layers (builtin:spheres:N)")
plt.ylabel("frame time, ms (median of 3)")
plt.title(f"strata on {device.label}, {args.size}x{args.size}")
plt.legend()
plt.grid(alpha=0.3)
plt.savefig(args.out, dpi=120)
print("wrote", args.out)
