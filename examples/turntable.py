#!/usr/bin/python3
"""A turntable: a mesh seen from all around, written as an animated GIF (Pillow), with each
frame's time; one Renderer renders every view of the geometry it prepared once.

    python3 examples/turntable.py [MESH] [--frames 36] [--size 256] [--method cells] [--out FILE]
"""
import argparse

from PIL import Image  # type: ignore[import]

import strata


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("mesh", nargs="?", default="builtin:demo", help="a mesh file or builtin:NAME")
    parser.add_argument("--frames", type=int, default=36)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--method", default="cells")
    parser.add_argument("--out", default="turntable.gif")
    args = parser.parse_args()

    r = strata.Renderer(strata.Device(), args.method)
    r.set_geometry(strata.load(args.mesh))
    elevation = r.geometry.natural_view()["el"] if r.geometry else 20.0
    frames = []
    for i in range(args.frames):
        image = r.render(az=360.0 * i / args.frames, el=elevation, width=args.size,
                         height=args.size)
        frames.append(Image.fromarray(image[..., :3]))
        print(f"frame {i + 1}/{args.frames}: {r.stats['frame_ms']['median']:.1f} ms")
    frames[0].save(args.out, save_all=True, append_images=frames[1:], duration=80, loop=0)
    print("wrote", args.out)


if __name__ == "__main__":
    main()
