#!/usr/bin/python3
"""A mesh from NumPy arrays: a Z-up torus with a colour per triangle, seen with a look-at camera
whose up is +Z (as meshes from trimesh or CAD usually are), rendered exactly with `cells` and by
the Embree reference, the difference measured, and every layer under the deepest pixel picked.

    python3 examples/numpy_mesh.py [--size 256] [--out DIR]
"""
import argparse
import os

import numpy as np
import numpy.typing as npt

import strata


def torus(rings: int, sides: int) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.int64]]:
    """A torus about the Z axis: (positions, triangle indices), counter-clockwise outwards."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, rings, endpoint=False),
                       np.linspace(0, 2 * np.pi, sides, endpoint=False), indexing="ij")
    r = 1.0 + 0.35 * np.cos(v)
    positions = np.stack([r * np.cos(u), r * np.sin(u), 0.35 * np.sin(v)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(rings), np.arange(sides), indexing="ij")
    a = i * sides + j
    b = ((i + 1) % rings) * sides + j
    c = ((i + 1) % rings) * sides + (j + 1) % sides
    d = i * sides + (j + 1) % sides
    indices = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                              np.stack([a, c, d], -1).reshape(-1, 3)])
    return positions.astype(np.float32), indices.astype(np.int64)


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--out", default=".")
    args = parser.parse_args()

    positions, indices = torus(48, 24)
    # Colour by height: a ramp from blue (bottom) to orange (top), opacity 0.4.
    z = positions[indices].mean(axis=1)[:, 2]
    t = (z - z.min()) / (z.max() - z.min())
    colors = np.stack([0.2 + 0.8 * t, 0.4 + 0.1 * t, 1.0 - 0.8 * t, np.full_like(t, 0.4)], -1)
    mesh = strata.from_arrays(positions, indices, colors)
    print(mesh)

    device = strata.Device()
    eye, target, up = (3.0, -3.0, 2.2), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)
    images = {}
    deepest = (0, 0)
    for method in ("cells", "embree"):
        r = strata.Renderer(device, method, background=(1.0, 1.0, 1.0),
                            depth_complexity=method == "cells")
        r.set_geometry(mesh)
        images[method] = r.render(eye=eye, target=target, up=up, width=args.size,
                                  height=args.size)
        if r.depth_complexity is not None:  # fragments per pixel: the deepest pixel is picked
            y, x = np.unravel_index(int(np.argmax(r.depth_complexity)), r.depth_complexity.shape)
            deepest = (int(x), int(y))
        os.makedirs(args.out, exist_ok=True)
        strata.save_image(os.path.join(args.out, f"torus-{method}.png"), images[method])
    diff = np.abs(images["cells"].astype(int) - images["embree"].astype(int))[..., :3].max(axis=2)
    print(f"cells against embree: {float((diff <= 2).mean()):.2%} of pixels within 2/255, "
          f"largest difference {int(diff.max())}/255")

    picker = strata.Picker(device)
    picker.set_geometry(mesh)
    hit = picker.pick([deepest], all_layers=True, eye=eye, target=target, up=up,
                      width=args.size, height=args.size)[0]
    print(f"pixel {deepest}: {len(hit.get('layers', []))} layers")
    for layer in hit.get("layers", []):
        print(f"  layer at depth {layer['depth']:.3f}: triangle {layer['triangle']}, "
              f"{'front' if layer['front_facing'] else 'back'} face, "
              f"light let through {layer['transmittance']:.2f}")


if __name__ == "__main__":
    main()
