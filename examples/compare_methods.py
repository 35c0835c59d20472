#!/usr/bin/python3
"""Methods against depth: frame time and fragments of strata's methods on the stacked-spheres
depth test (builtin:spheres:N, N layers), seen along the stack as the scene's own view shows
it, so every pixel of the centre holds N fragments. One line per method, saved as a plot
(matplotlib) and as JSON.

    python3 examples/compare_methods.py [--size 256] [--depths 16,32,48,64] [--out DIR]
"""
import argparse
import json
import os

import matplotlib  # type: ignore[import]

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # type: ignore[import]

import strata


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--size", type=int, default=256, help="image width and height")
    parser.add_argument("--depths", default="16,32,48,64", help="the N of builtin:spheres:N")
    parser.add_argument("--methods", default="cells,ppll,abuffer,dp,ddp,embree")
    parser.add_argument("--frames", type=int, default=3, help="frames per measurement")
    parser.add_argument("--out", default=".", help="folder for methods-vs-depth.png/.json")
    args = parser.parse_args()

    device = strata.Device()
    depths = [int(d) for d in args.depths.split(",")]
    results: dict[str, list[dict[str, float]]] = {m: [] for m in args.methods.split(",")}
    for depth in depths:
        geometry = strata.load(f"builtin:spheres:{depth}")
        for method, rows in results.items():
            r = strata.Renderer(device, method, frames=args.frames, k=max(depth, 16))
            r.set_geometry(geometry)
            r.render(width=args.size, height=args.size)  # the scene's own view: along the stack
            stats = r.stats
            rows.append({"depth": depth, "ms": stats["frame_ms"]["median"],
                         "fragments": stats["fragments"],
                         "max_depth_complexity": stats["max_depth_complexity"]})
            print(f"{method:8s} N {depth:3d}: {rows[-1]['ms']:8.2f} ms, "
                  f"{stats['fragments']} fragments, depth {stats['max_depth_complexity']}")

    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "methods-vs-depth.json"), "w") as f:
        json.dump({"device": device.label, "size": args.size, "results": results}, f, indent=1)
    for method, rows in results.items():
        plt.plot([r["depth"] for r in rows], [r["ms"] for r in rows], marker="o", label=method)
    plt.xlabel("depth layers (builtin:spheres:N, seen along the stack)")
    plt.ylabel(f"frame time, ms (median of {args.frames})")
    plt.title(f"strata on {device.label}, {args.size}x{args.size}", fontsize=8)
    plt.legend()
    plt.grid(alpha=0.3)
    path = os.path.join(args.out, "methods-vs-depth.png")
    plt.savefig(path, dpi=120)
    print("wrote", path)


if __name__ == "__main__":
    main()
