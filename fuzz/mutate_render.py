#!/usr/bin/python3
"""Mutation fuzz of the whole command line: renders mutated scene files at 64x64 and checks
that each run either renders or fails with one line "strata: error: ..." naming the file, with
no signal and no hang (a run over --timeout seconds, twice). Complements the libFuzzer targets,
which stop at loading: this one also renders what loads (depth complexity, huge polygons), with
every method family: the first of --methods on every mutant, the others on each mutant the first
rendered (so a bound on work or memory is checked in every method, not only the first).

usage: mutate_render.py STRATA SEEDS_FOLDER OUT_FOLDER [--count N] [--jobs J] [--timeout S]
                        [--methods M1,M2,...] [--seed R] [--formats fuzz_obj,fuzz_ply,...]
SEEDS_FOLDER holds one folder per format (fuzz_obj, fuzz_ply, ...), as fuzz/make_corpus.py
writes them; each seed's main file is mutated, its companions (MTL, buffers, images) are written
beside it as they are. Failing inputs are kept in OUT_FOLDER/failures.
"""
import argparse
import concurrent.futures
import os
import random
import re
import shutil
import subprocess
import sys
from pathlib import Path

FORMATS = {"fuzz_obj": ".obj", "fuzz_ply": ".ply", "fuzz_off": ".off", "fuzz_stl": ".stl",
           "fuzz_gltf": ".gltf", "fuzz_glb": ".glb", "fuzz_gltf1": ".gltf"}
NUMBERS = [b"0", b"-1", b"1e38", b"-1e38", b"nan", b"inf", b"4294967295", b"2147483648",
           b"99999999999", b"1e-45", b"65536", b"3"]


def mutate(data, rng):
    data = bytearray(data)
    for _ in range(rng.randint(1, 6)):
        kind = rng.randrange(7)
        if not data:
            data = bytearray(b"\n")
        at = rng.randrange(len(data))
        if kind == 0:  # flip a byte
            data[at] = rng.randrange(256)
        elif kind == 1:  # cut here
            del data[at:]
        elif kind == 2:  # delete a run
            del data[at:at + rng.randint(1, 64)]
        elif kind == 3:  # repeat a run many times (depth, polygon size)
            run = data[at:at + rng.randint(1, 200)]
            data[at:at] = run * rng.randint(2, 2000)
        elif kind == 4:  # replace a number
            nums = [m.span() for m in re.finditer(rb"-?[0-9]+(\.[0-9]+)?", bytes(data))]
            if nums:
                a, b = rng.choice(nums)
                data[a:b] = rng.choice(NUMBERS)
        elif kind == 5:  # insert random bytes
            data[at:at] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
        else:  # duplicate a line
            lines = bytes(data).split(b"\n")
            i = rng.randrange(len(lines))
            lines[i:i] = [lines[i]] * rng.randint(1, 500)
            data = bytearray(b"\n".join(lines))
    return bytes(data)


def split_seed(data):
    """(main file, [(companion name, bytes)]) of a seed with "@@file NAME" sections."""
    parts = data.split(b"\n@@file ")
    companions = []
    for part in parts[1:]:
        name, _, body = part.partition(b"\n")
        name = name.decode("latin-1")
        if re.fullmatch(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}", name):
            companions.append((name, body))
    return parts[0], companions


def run_methods(strata, path, timeout, methods):
    """(kind, method, detail) of the first failure of the methods on `path`, else of the first
    method's run: each further method only once the first has rendered the file."""
    kind, detail = run_one(strata, path, timeout, methods[0])
    if kind != "rendered":
        return kind, methods[0], detail
    for method in methods[1:]:
        other, detail = run_one(strata, path, timeout, method)
        if other not in ("rendered", "error"):
            return other, method, detail
    return kind, methods[0], ""


def run_one(strata, path, timeout, method):
    command = [strata, "render", str(path), "-m", method, "-s", "64x64",
               "-o", str(path.with_suffix(f".{method}.png"))]
    # A run over the timeout is tried once more: a stall of the machine (other jobs, the OpenCL
    # driver compiling its kernels after a cache change) is not a hang, and a real hang repeats.
    for attempt in range(2):
        try:
            p = subprocess.run(command, capture_output=True, timeout=timeout)
            break
        except subprocess.TimeoutExpired:
            if attempt == 1:
                return "hang", ""
    err = p.stderr.decode("utf-8", "replace").strip()
    if p.returncode < 0 or p.returncode > 1:
        return "signal", f"exit {p.returncode}: {err[-300:]}"
    if p.returncode == 0:
        return "rendered", ""
    lines = err.split("\n")
    errors = [l for l in lines if l.startswith("strata: error:")]
    if len(errors) != 1 or len(lines) - sum(l.startswith("strata: ") for l in lines) > 0:
        return "message", err[:300]
    if path.name not in errors[0] or len(errors[0]) > 600:
        return "message", errors[0][:300]
    return "error", ""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("strata")
    ap.add_argument("seeds")
    ap.add_argument("out")
    ap.add_argument("--count", type=int, default=2000, help="mutants per format")
    ap.add_argument("--jobs", type=int, default=os.cpu_count())
    ap.add_argument("--timeout", type=float, default=30.0)
    ap.add_argument("--methods", default="ppll,cells,octree,abuffer,embree",
                    help="methods, comma-separated: the first renders every mutant, the others "
                         "each mutant the first rendered")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--formats", default=",".join(FORMATS),
                    help="comma-separated seed folders to mutate (default: all)")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    out = Path(a.out)
    work = out / "work"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    total_bad = 0
    for fmt in a.formats.split(","):
        ext = FORMATS[fmt]
        seeds = [split_seed(p.read_bytes())
                 for p in sorted((Path(a.seeds) / fmt).glob("*")) if p.is_file()]
        if not seeds:
            print(f"{fmt}: no seeds")
            continue
        jobs = []
        for i in range(a.count):
            folder = work / f"{fmt}-{i:05d}"
            folder.mkdir()
            main_bytes, companions = rng.choice(seeds)
            for name, data in companions:
                (folder / name).write_bytes(data)
            path = folder / f"{fmt}-{i:05d}{ext}"
            path.write_bytes(mutate(main_bytes, rng))
            jobs.append(path)
        counts = {}
        methods = [m for m in a.methods.split(",") if m]
        with concurrent.futures.ThreadPoolExecutor(a.jobs) as pool:
            for path, (kind, method, detail) in zip(jobs, pool.map(
                    lambda p: run_methods(a.strata, p, a.timeout, methods), jobs)):
                counts[kind] = counts.get(kind, 0) + 1
                if kind in ("hang", "signal", "message"):
                    total_bad += 1
                    keep = out / "failures"
                    keep.mkdir(exist_ok=True)
                    shutil.copytree(path.parent, keep / path.parent.name, dirs_exist_ok=True)
                    print(f"  {kind} ({method}): {path.name}: {detail}")
                shutil.rmtree(path.parent, ignore_errors=True)
        print(f"{fmt}: {a.count} mutants: " +
              ", ".join(f"{k} {v}" for k, v in sorted(counts.items())), flush=True)
    shutil.rmtree(work, ignore_errors=True)
    sys.exit(1 if total_bad else 0)


if __name__ == "__main__":
    main()
