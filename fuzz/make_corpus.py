#!/usr/bin/python3
"""Builds the seed corpora of the scene-file and texture fuzz targets.

Seeds are the small real files of tests/ and of Debian's assimp-testmodels. A seed is the main
file followed by its companions (an OBJ's MTL and textures, a glTF's buffers and images), each
introduced by a line "@@file NAME" (fuzz/fuzz_support.h splits them again).

usage: make_corpus.py OUTPUT_FOLDER
"""
import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ASSIMP = Path("/usr/share/assimp/models")
MAX_MAIN = 96 * 1024       # larger files only slow the mutator down
MAX_COMPANION = 48 * 1024
NAME_OK = re.compile(r"^[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}$")


def files(folder, *suffixes):
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.rglob("*")
                  if p.is_file() and p.suffix.lower() in suffixes and p.stat().st_size <= MAX_MAIN)


def companion(main, name):
    """The bytes of a companion referenced from `main` as `name`, as a section, or b''."""
    if not NAME_OK.match(name):
        return b""
    path = main.parent / name
    if not path.is_file() or path.stat().st_size > MAX_COMPANION:
        return b""
    return b"\n@@file " + name.encode() + b"\n" + path.read_bytes()


def obj_seed(path):
    data = path.read_bytes()
    out = data
    for m in re.finditer(rb"^mtllib\s+(\S+)", data, re.M):
        name = m.group(1).decode("latin-1")
        section = companion(path, name)
        out += section
        if section:
            mtl = (path.parent / name).read_bytes()
            for t in re.finditer(rb"^\s*map_Kd\s+(?:-\S+\s+\S+\s+)*(\S+)", mtl, re.M):
                out += companion(path, t.group(1).decode("latin-1"))
    return out


def gltf_seed(path):
    data = path.read_bytes()
    out = data
    for m in re.finditer(rb'"uri"\s*:\s*"([^"]+)"', data):
        uri = m.group(1).decode("latin-1")
        if not uri.startswith("data:"):
            out += companion(path, uri)
    return out


def gltf_version(path):
    head = path.read_bytes()[:4096]
    m = re.search(rb'"version"\s*:\s*"?([0-9.]+)', head)
    return m.group(1).decode() if m else "?"


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = Path(sys.argv[1])
    seeds = {t: [] for t in ["fuzz_obj", "fuzz_ply", "fuzz_off", "fuzz_stl", "fuzz_gltf",
                             "fuzz_glb", "fuzz_gltf1", "fuzz_texture"]}
    data = ROOT / "tests" / "data"
    for p in files(data, ".obj") + files(ASSIMP / "OBJ", ".obj"):
        seeds["fuzz_obj"].append((p, obj_seed(p)))
    for p in files(data, ".ply") + files(ASSIMP / "PLY", ".ply"):
        seeds["fuzz_ply"].append((p, p.read_bytes()))
    for p in files(ASSIMP / "OFF", ".off"):
        seeds["fuzz_off"].append((p, p.read_bytes()))
    for p in files(ASSIMP / "STL", ".stl"):
        seeds["fuzz_stl"].append((p, p.read_bytes()))
    for p in files(data / "gltf", ".gltf") + files(ASSIMP / "glTF2", ".gltf"):
        seeds["fuzz_gltf"].append((p, gltf_seed(p)))
    for p in files(ASSIMP / "glTF", ".gltf"):
        seeds["fuzz_gltf1"].append((p, gltf_seed(p)))
    for p in files(ASSIMP / "glTF2", ".glb") + files(ASSIMP / "glTF", ".glb"):
        seeds["fuzz_glb"].append((p, p.read_bytes()))
    for p in files(ASSIMP, ".png", ".jpg", ".jpeg", ".bmp", ".tga"):
        if p.stat().st_size <= MAX_COMPANION:
            seeds["fuzz_texture"].append((p, p.read_bytes()))
    # Small hand-written seeds, so no target starts empty whatever the system provides.
    seeds["fuzz_off"].append((Path("tetra.off"), b"OFF\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                              b"3 0 2 1\n3 0 1 3\n3 0 3 2\n4 1 2 3 1\n"))
    seeds["fuzz_stl"].append((Path("tri.stl"), b"solid t\nfacet normal 0 0 1\nouter loop\n"
                              b"vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
                              b"endsolid t\n"))
    seeds["fuzz_obj"].append((Path("quad.obj"), b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\n"
                              b"v 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl a\n"
                              b"f 1/1 2/2 3/3 4/4\n@@file m.mtl\nnewmtl a\nKd 1 0 0\nd 0.5\n"))
    for target, items in seeds.items():
        folder = out / target
        folder.mkdir(parents=True, exist_ok=True)
        for i, (path, data) in enumerate(items):
            (folder / f"seed-{i:03d}-{path.name}").write_bytes(data)
        print(f"{target}: {len(items)} seeds")


if __name__ == "__main__":
    main()
