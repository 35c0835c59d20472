"""The examples run, and their outputs say what they should: the depth example's fragments grow
with the layers, the NumPy mesh renders as Embree does, the turntable has its frames; mypy
--strict passes on them against the module's stubs, and stubtest finds the stubs true.

Run by ctest (python_examples) with PYTHONPATH and MYPYPATH at the built module and its stubs."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
EXAMPLES = sorted(p for p in HERE.glob("*.py") if not p.name.startswith("test_"))


def run(script, *args, cwd):
    proc = subprocess.run([sys.executable, str(HERE / script), *args], cwd=cwd,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def test_depth_example_sees_every_layer(tmp_path):
    run("compare_methods.py", "--depths", "16,32", "--size", "64", "--methods", "cells,ppll",
        "--frames", "1", "--out", str(tmp_path), cwd=tmp_path)
    results = json.loads((tmp_path / "methods-vs-depth.json").read_text())["results"]
    assert (tmp_path / "methods-vs-depth.png").stat().st_size > 0
    for method, rows in results.items():
        assert [r["depth"] for r in rows] == [16, 32]
        # Seen along the stack, the centre pixels hold every layer: the fragments about double.
        assert rows[1]["fragments"] > 1.6 * rows[0]["fragments"], (method, rows)
        assert rows[0]["max_depth_complexity"] >= 16 and rows[1]["max_depth_complexity"] >= 32


def test_numpy_example_matches_embree(tmp_path):
    out = run("numpy_mesh.py", "--size", "96", "--out", str(tmp_path), cwd=tmp_path)
    within = float(re.search(r"([0-9.]+)% of pixels within 2/255", out).group(1))
    assert within >= 99.5, out
    assert (tmp_path / "torus-cells.png").exists() and (tmp_path / "torus-embree.png").exists()
    layers = re.findall(r"layer at depth", out)
    assert len(layers) >= 2 and len(layers) % 2 == 0, out  # a closed torus: in and out pairs


def test_turntable_writes_its_frames(tmp_path):
    from PIL import Image
    gif = tmp_path / "turn.gif"
    out = run("turntable.py", "--frames", "4", "--size", "48", "--out", str(gif), cwd=tmp_path)
    assert "frame 4/4" in out
    with Image.open(gif) as im:
        assert im.n_frames == 4 and im.size == (48, 48)


def mypy(*args):
    proc = subprocess.run([sys.executable, "-m", "mypy", *args], capture_output=True, text=True,
                          timeout=900, env=dict(os.environ, MYPY_CACHE_DIR=os.devnull))
    return proc.returncode, proc.stdout + proc.stderr


def test_examples_pass_mypy_strict():
    rc, out = mypy("--strict", "--no-incremental", *map(str, EXAMPLES))
    assert rc == 0, out


def test_stubs_match_the_module():
    allowlist = HERE.parent / "python" / "stubtest-allowlist.txt"
    proc = subprocess.run([sys.executable, "-m", "mypy.stubtest", "strata", "--allowlist",
                           str(allowlist)], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
