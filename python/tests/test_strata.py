"""The Python module: devices, geometry from files and arrays, every exact method against the
Embree reference, picking, bad input raised as strata.InputError and a missing device as
strata.DeviceError (both strata.Error)."""
import os

import numpy as np
import pytest

import strata

MODELS = os.environ.get("STRATA_MODELS_DIR", os.path.join(os.path.dirname(__file__), "../../tests/models"))
OUT = os.environ.get("STRATA_TEST_OUTPUT_DIR", "/tmp/strata-python-tests")
SIZE = 128


@pytest.fixture(scope="module")
def device():
    return strata.Device()


def render(device, method, geometry, **view):
    r = strata.Renderer(device, method)
    r.set_geometry(geometry)
    return r.render(width=SIZE, height=SIZE, **view), r.stats


def max_difference(a, b):
    return int(np.abs(a[..., :3].astype(int) - b[..., :3].astype(int)).max())


def test_methods_and_devices_are_listed(device):
    names = [m["name"] for m in strata.methods()]
    assert "cells" in names and "embree" in names and "ppll" in names
    assert any(m["translucency"] for m in strata.methods())
    assert strata.devices()
    assert device.label


@pytest.mark.parametrize("model", ["teapot.obj", "cow.obj"])
def test_exact_methods_match_embree(device, model):
    g = strata.load(os.path.join(MODELS, model))
    reference, _ = render(device, "embree", g, az=35, el=25)
    assert reference.shape == (SIZE, SIZE, 4) and reference.dtype == np.uint8
    for m in strata.methods():
        if not m["exact"] or m["name"] in ("embree", "opaque"):
            continue
        image, stats = render(device, m["name"], g, az=35, el=25)
        diff = np.abs(image[..., :3].astype(int) - reference[..., :3].astype(int)).max(axis=2)
        within = float((diff <= 2).mean())
        if within < 0.999:
            os.makedirs(OUT, exist_ok=True)
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            for name, im in (("rendered", image), ("reference", reference),
                             ("difference", np.minimum(diff * 8, 255).astype(np.uint8))):
                plt.imsave(os.path.join(OUT, f"{model}-{m['name']}-{name}.png"), im)
        assert within >= 0.999, f"{m['name']} on {model}: {within:.4%} of pixels within 2/255"
        assert stats["method"] == m["name"] and stats["fragments"] > 0


def test_translucency_only_where_supported(device):
    g = strata.load("builtin:demo")
    r = strata.Renderer(device, "cells", effect="translucency")
    r.set_geometry(g)
    assert r.render(width=64, height=64).shape == (64, 64, 4)
    ppll = strata.Renderer(device, "ppll", effect="translucency")
    ppll.set_geometry(g)
    with pytest.raises(strata.Error, match="translucency"):
        ppll.render(width=64, height=64)


def test_numpy_geometry_equals_the_file(device, tmp_path):
    # A mesh written as OBJ from the arrays, then loaded: both must render identically.
    rng = np.random.default_rng(7)
    u, v = np.meshgrid(np.linspace(0, np.pi, 12), np.linspace(0, 2 * np.pi, 24))
    positions = np.stack([np.sin(u) * np.cos(v), np.cos(u), np.sin(u) * np.sin(v)], -1).reshape(-1, 3)
    positions += rng.normal(scale=0.01, size=positions.shape)
    grid = np.arange(12 * 24).reshape(24, 12)
    a, b, c, d = grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]
    indices = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    path = tmp_path / "sphere.obj"
    with open(path, "w") as f:
        for p in positions:
            f.write("v %.9g %.9g %.9g\n" % tuple(p))
        for t in indices + 1:
            f.write("f %d %d %d\n" % tuple(t))
    from_file = strata.load(str(path))
    from_arrays = strata.from_arrays(positions.astype(np.float32), indices)
    assert from_file.triangle_count == from_arrays.triangle_count
    for method in ("ppll", "cells"):
        x, _ = render(device, method, from_file)
        y, _ = render(device, method, from_arrays)
        assert max_difference(x, y) == 0, method


def test_per_triangle_colours(device):
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    indices = np.array([[0, 1, 2], [1, 3, 2]])
    colors = np.array([[1, 0, 0, 1], [0, 0, 1, 1]], np.float32)
    g = strata.from_arrays(positions, indices, colors)
    image, _ = render(device, "opaque", g, az=0, el=0)
    assert image[..., 0].max() > 100 and image[..., 2].max() > 100


@pytest.mark.parametrize("positions,indices,message", [
    (np.zeros((4, 2), np.float32), np.array([[0, 1, 2]]), "shape"),
    (np.zeros((4,), np.float32), np.array([[0, 1, 2]]), "shape"),
    (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], np.float32), np.array([[0, 1, 2]]), "finite"),
    (np.eye(3, dtype=np.float32), np.array([[0, 1, 3]]), "past"),
    (np.eye(3, dtype=np.float32), np.array([[0, 1, -1]]), "not a vertex index"),
    (np.eye(3, dtype=np.float32), np.array([[0.0, 1.0, 2.0]]), "integer"),
    (np.eye(3, dtype=np.float32), np.array([[0, 1]]), "shape"),
])
def test_bad_arrays_raise(positions, indices, message):
    with pytest.raises(strata.Error, match=message):
        strata.from_arrays(positions, indices)


def test_bad_input_raises(device):
    with pytest.raises(strata.Error, match="unknown method"):
        strata.Renderer(device, "nope")
    with pytest.raises(strata.Error):
        strata.load("/no/such/file.obj")
    r = strata.Renderer(device, "ppll")
    with pytest.raises(strata.Error, match="setGeometry"):
        r.render()
    r.set_geometry(strata.load("builtin:demo"))
    with pytest.raises(strata.Error):
        r.render(width=0, height=10)
    with pytest.raises(strata.InputError):
        strata.Device("surely-no-such-device")


def test_errors_form_a_hierarchy():
    assert issubclass(strata.InputError, strata.Error) and issubclass(strata.InputError, ValueError)
    assert issubclass(strata.DeviceError, strata.Error)
    assert issubclass(strata.DeviceError, RuntimeError)
    assert issubclass(strata.OutOfMemoryError, strata.Error)
    assert issubclass(strata.OutOfMemoryError, MemoryError)
    assert not issubclass(strata.DeviceError, ValueError)
    with pytest.raises(strata.InputError, match="no/such/file.obj"):
        strata.load("/no/such/file.obj")
    with pytest.raises(ValueError, match="unknown method"):
        strata.Renderer(strata.Device(), "nope")
    assert strata.__version__.count(".") == 2


def test_no_device_is_a_device_error():
    """With no OpenCL driver to load (an empty vendor folder), opening a device is a DeviceError."""
    import subprocess
    import sys
    import tempfile
    code = ("import strata\n"
            "try:\n"
            "    strata.Device()\n"
            "except strata.DeviceError as e:\n"
            "    print('DeviceError', isinstance(e, RuntimeError), e)\n")
    with tempfile.TemporaryDirectory() as empty:
        env = dict(os.environ, OCL_ICD_VENDORS=empty, OCL_ICD_FILENAMES="")
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, timeout=120)
    assert out.stdout.startswith("DeviceError True no OpenCL device found"), out.stdout + out.stderr


def test_tile_kernel_forms_agree(device):
    g = strata.load(os.path.join(MODELS, "teapot.obj"))
    for method in ("opaque", "ppll", "abuffer", "cells"):
        images = {}
        for form in ("group", "serial"):
            r = strata.Renderer(device, method, k=64, tile_kernels=form)
            r.set_geometry(g)
            images[form] = r.render(az=35, el=25, width=96, height=80)
            assert r.stats["tile_kernels"] == form
        assert max_difference(images["group"], images["serial"]) == 0, method
    with pytest.raises(strata.Error, match="fastest"):
        r = strata.Renderer(device, "ppll", tile_kernels="fastest")
        r.set_geometry(g)
        r.render()


def test_one_geometry_many_views(device):
    g = strata.load("builtin:demo")
    r = strata.Renderer(device, "cells", depth_complexity=True)
    r.set_geometry(g)
    images = [r.render(az=az, width=64, height=64) for az in (0, 90, 180)]
    assert max_difference(images[0], images[1]) > 0
    assert r.depth_complexity.shape == (64, 64)
    assert int(r.depth_complexity.max()) == r.stats["max_depth_complexity"]


def test_geometry_is_uploaded_once(device):
    g = strata.load("builtin:demo")
    r = strata.Renderer(device, "ppll")
    r.set_geometry(g)
    r.render(az=0, width=64, height=64)
    assert r.stats["scene_upload_bytes"] > 0
    again = r.render(az=90, width=64, height=64)
    assert r.stats["scene_upload_bytes"] == 0
    r2 = strata.Renderer(device, "ppll")
    r2.set_geometry(g)
    assert max_difference(again, r2.render(az=90, width=64, height=64)) == 0
    r.set_geometry(strata.load("builtin:spheres:16"))  # a new geometry is uploaded
    r.render(az=90, width=64, height=64)
    assert r.stats["scene_upload_bytes"] > 0


def test_picking(device):
    g = strata.load("builtin:demo")
    p = strata.Picker(device)
    p.set_geometry(g)
    hits = p.pick([(64, 64), (0, 0)], width=128, height=128)
    assert len(hits) == 2
    assert hits[0]["hit"] and hits[0]["depth"] > 0


def test_octree_variants_and_memory_budget(device):
    g = strata.load(os.path.join(MODELS, "horse.ply"))
    reference, _ = render(device, "embree", g, az=60, el=10)
    images = {}
    for variant in ("kbuffer", "blocks-histogram", "dp"):
        r = strata.Renderer(device, "octree", octree_variant=variant, leaf_tris=3000,
                            cache_dir=os.path.join(OUT, "octree-cache"))
        r.set_geometry(g)
        images[variant] = r.render(az=60, el=10, width=SIZE, height=SIZE)
        assert r.stats["octree_variant"] == variant
        assert max_difference(images[variant], reference) <= 2 or \
            float((np.abs(images[variant][..., :3].astype(int) - reference[..., :3].astype(int)).max(axis=2) <= 2).mean()) >= 0.995
    bounded = strata.Renderer(device, "octree", leaf_tris=3000, memory_budget_mb=3,
                              cache_dir=os.path.join(OUT, "octree-cache"))
    bounded.set_geometry(g)
    image = bounded.render(az=60, el=10, width=SIZE, height=SIZE)
    assert bounded.stats["peak_device_bytes"] <= 3 * 1024 * 1024
    assert max_difference(image, images["kbuffer"]) <= 1
    with pytest.raises(strata.Error, match="too small"):
        tiny = strata.Renderer(device, "octree", memory_budget_mb=0.01)
        tiny.set_geometry(g)
        tiny.render(width=SIZE, height=SIZE)
