"""The module under threads and memory exhaustion: one Renderer shared by threads, geometry
replaced mid-render, separate Renderers at once, memory that cannot be had, and views that cannot
be framed. Each case that could end the interpreter runs in a subprocess, so a signal is a test
failure, not the end of the test run."""
import os
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest

import strata

SIZE = 96


@pytest.fixture(scope="module")
def device():
    return strata.Device()


def run_python(code, address_space_bytes=None, timeout=300):
    """Runs `code` in a fresh interpreter, its address space limited by the shell's ulimit if
    asked (not preexec_fn: this process has the OpenCL driver's threads running); returns it.
    One BLAS thread, so what NumPy reserves does not grow with the machine's cores."""
    command = [sys.executable, "-c", code]
    if address_space_bytes:
        command = ["sh", "-c", f'ulimit -v {address_space_bytes // 1024}; exec "$0" "$@"'] + command
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout, env=env)


def assert_no_signal(proc):
    assert proc.returncode >= 0, (
        f"killed by {signal.Signals(-proc.returncode).name}: {proc.stderr[-2000:]}")


def failures_in_threads(work, args):
    """Runs work(arg) on a thread per arg at once; returns what they found wrong or raised."""
    failures = []

    def guarded(arg):
        try:
            failures.extend(work(arg))
        except Exception as e:  # noqa: BLE001 - returned to the test
            failures.append(f"{arg}: {type(e).__name__}: {e}")

    threads = [threading.Thread(target=guarded, args=(a,)) for a in args]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return failures


def test_one_renderer_shared_by_threads(device):
    """Calls on one Renderer are serialised: every thread's frames equal single-threaded ones."""
    g = strata.load("builtin:spheres:16")
    for method in ["ppll", "cells", "octree", "abuffer"]:
        r = strata.Renderer(device, method)
        r.set_geometry(g)
        expected = {az: r.render(az=az, width=SIZE, height=SIZE).copy() for az in (30, 31, 32, 33)}

        def work(az):
            return [f"{method}: az {az} differs" for _ in range(3)
                    if not np.array_equal(r.render(az=az, width=SIZE, height=SIZE), expected[az])]

        failures = failures_in_threads(work, list(expected))
        assert not failures, failures


def test_geometry_replaced_during_renders(device):
    """set_geometry while another thread renders: each frame is wholly one scene's.
    Each geometry is loaded afresh, so the renderer holds the only reference to it."""
    scenes = ["builtin:spheres:16", "builtin:demo"]
    r = strata.Renderer(device, "ppll")
    images = {}
    for name in scenes:
        r.set_geometry(strata.load(name))
        images[name] = r.render(width=SIZE, height=SIZE).copy()
    stop = threading.Event()
    failures = []

    def work():
        try:
            while not stop.is_set():
                image = r.render(width=SIZE, height=SIZE)
                if not any(np.array_equal(image, e) for e in images.values()):
                    failures.append("a frame that is neither scene's")
        except Exception as e:  # noqa: BLE001 - reported below
            failures.append(f"{type(e).__name__}: {e}")

    t = threading.Thread(target=work)
    t.start()
    for i in range(20):
        r.set_geometry(strata.load(scenes[i % 2]))
    stop.set()
    t.join()
    assert not failures, failures


def test_separate_renderers_render_at_once(device):
    """N threads x M frames, a Renderer each on one Device: images equal single-threaded ones."""
    g = strata.load("builtin:demo")
    methods = ["ppll", "cells", "opaque", "mdts", "octree", "embree"]
    expected = {}
    for m in methods:
        r = strata.Renderer(device, m)
        r.set_geometry(g)
        expected[m] = r.render(az=40, width=SIZE, height=SIZE).copy()

    def work(method):
        r = strata.Renderer(device, method)
        r.set_geometry(g)
        return [f"{method} differs" for _ in range(4)
                if not np.array_equal(r.render(az=40, width=SIZE, height=SIZE), expected[method])]

    failures = failures_in_threads(work, methods)
    assert not failures, failures


OUT_OF_MEMORY_RENDER = """
import strata
r = strata.Renderer(strata.Device(), {method!r})
r.set_geometry(strata.load("builtin:demo"))
try:
    r.render(width=16384, height=16384)
    print("rendered")
except strata.OutOfMemoryError as e:
    assert isinstance(e, MemoryError) and isinstance(e, strata.Error)
    print("out of memory:", e)
except strata.Error as e:
    print("error:", e)
"""


@pytest.mark.parametrize("method", [m["name"] for m in strata.methods()])
def test_render_out_of_memory_raises(method):
    """A 16384x16384 frame under a 1.5 GB address space: an exception, never a signal."""
    proc = run_python(OUT_OF_MEMORY_RENDER.format(method=method), 1500 << 20)
    assert_no_signal(proc)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout.strip()
    assert out.startswith("out of memory:") or (
        out.startswith("error:") and "largest allocation" in out), out
    assert "\n" not in out


def test_arrays_out_of_memory_raise():
    """A valid 1 GiB int64 index array under a 2 GB address space: OutOfMemoryError."""
    code = """
import numpy as np, strata
p = np.random.default_rng(1).random((1000, 3), dtype=np.float32)
i = np.random.default_rng(2).integers(0, 1000, size=((1 << 30) // 24, 3), dtype=np.int64)
try:
    g = strata.from_arrays(p, i)
    r = strata.Renderer(strata.Device(), "ppll")
    r.set_geometry(g)
    r.render(width=64, height=64)
    print("rendered")
except strata.OutOfMemoryError as e:
    print("out of memory:", e)
"""
    proc = run_python(code, 2 << 30)
    assert_no_signal(proc)
    assert proc.stdout.startswith("out of memory:"), proc.stdout + proc.stderr[-2000:]


def test_far_unused_vertex_does_not_frame_the_view(device):
    """A vertex used by no kept triangle (1e19 away) neither frames the view nor aborts embree."""
    near = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    far = np.vstack([near, [[0, 0, 1e19]]]).astype(np.float32)
    plain = strata.from_arrays(near, np.array([[0, 1, 2]]))
    with_far = strata.from_arrays(far, np.array([[0, 1, 2], [0, 1, 1]]))  # 2nd: zero area, dropped
    assert with_far.bounding_sphere == plain.bounding_sphere
    for method in ["embree", "ppll", "cells", "octree"]:
        r = strata.Renderer(device, method)
        r.set_geometry(plain)
        expected = r.render(width=SIZE, height=SIZE).copy()
        r.set_geometry(with_far)
        assert np.array_equal(r.render(width=SIZE, height=SIZE), expected), method


@pytest.mark.parametrize("view, message", [
    (dict(az=float("nan")), "finite"),
    (dict(el=float("inf")), "finite"),
    (dict(distance=float("inf")), "distance"),
    (dict(distance=1e30), "within \\+-1e18"),
    (dict(distance=1e-30), "on its target"),
])
def test_views_that_cannot_be_framed_raise(device, view, message):
    for method in ["embree", "ppll", "cells"]:
        r = strata.Renderer(device, method)
        r.set_geometry(strata.load("builtin:demo"))
        with pytest.raises(strata.Error, match=message):
            r.render(width=32, height=32, **view)


@pytest.mark.parametrize("positions, indices, message", [
    (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=object), np.array([[0, 1, 2]]), "positions: expected an array of numbers"),
    (np.array([["0", "0", "0"], ["1", "0", "0"], ["0", "1", "0"]]), np.array([[0, 1, 2]]), "positions: expected an array of numbers"),
    (np.broadcast_to(np.zeros(3, np.float32), (1 << 40, 3)), np.array([[0, 1, 2]]), "positions: 1099511627776 rows"),
    (np.eye(3, dtype=np.float32), np.broadcast_to(np.arange(3), (1 << 40, 3)), "indices: 1099511627776 rows"),
])
def test_arrays_of_the_wrong_kind_name_the_argument(positions, indices, message):
    with pytest.raises(strata.Error, match=message):
        strata.from_arrays(positions, indices)
