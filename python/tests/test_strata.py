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
    with pytest.raises(strata.InputError, match="Renderer.render: no geometry: call set_geometry"):
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


def test_path_without_64bit_atomics(device):
    narrow = strata.Device(atomics="32")
    assert not narrow.int64_atomics
    g = strata.load(os.path.join(MODELS, "teapot.obj"))
    for method in ("ppll", "cells"):
        images = []
        for d in (device, narrow):
            r = strata.Renderer(d, method, k=64, tile_kernels="serial")
            r.set_geometry(g)
            images.append(r.render(az=35, el=25, width=96, height=80))
        assert max_difference(images[0], images[1]) == 0, method
    with pytest.raises(strata.Error, match="64-bit atomics"):
        r = strata.Renderer(narrow, "ppll", tile_kernels="group")
        r.set_geometry(g)
        r.render()
    with pytest.raises(strata.Error, match="auto, 64 or 32"):
        strata.Device(atomics="16")


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


def test_render_without_a_view_is_the_scene_own(device):
    """As `strata render` without --view: builtin:spheres:N along its stack, orthographic."""
    g = strata.load("builtin:spheres:16")
    natural = g.natural_view()
    assert natural["ortho"] is True and natural["ortho_height"] > 0
    r = strata.Renderer(device, "ppll")
    r.set_geometry(g)
    r.render(width=64, height=64)
    assert r.stats["max_depth_complexity"] >= 16
    r.render(az=30, el=20, width=64, height=64)  # across the stack: fewer layers
    assert r.stats["max_depth_complexity"] < 16
    same = r.render(az=natural["az"], el=natural["el"], ortho_height=natural["ortho_height"],
                    ortho=True, width=64, height=64)
    assert max_difference(same, r.render(width=64, height=64)) == 0


def test_look_at_with_z_up(device):
    """A Z-up mesh seen with up=(0, 0, 1) stands upright: a tall thin quad fills the image's
    height, not its width."""
    positions = np.array([[-0.1, 0, -1], [0.1, 0, -1], [0.1, 0, 1], [-0.1, 0, 1]], np.float32)
    g = strata.from_arrays(positions, np.array([[0, 1, 2], [0, 2, 3]]), alpha=1.0)
    r = strata.Renderer(device, "opaque", background=(1.0, 1.0, 1.0))
    r.set_geometry(g)
    image = r.render(eye=(0, -4, 0), target=(0, 0, 0), up=(0, 0, 1), width=64, height=64)
    covered = image[..., 0] < 200
    rows, cols = np.nonzero(covered)
    assert np.ptp(rows) > 3 * np.ptp(cols), (np.ptp(rows), np.ptp(cols))
    lying = r.render(eye=(0, -4, 0), target=(0, 0, 0), up=(1, 0, 0), width=64, height=64)
    rows, cols = np.nonzero(lying[..., 0] < 200)
    assert np.ptp(cols) > 3 * np.ptp(rows)
    with pytest.raises(strata.InputError, match="eye and target"):
        r.render(eye=(0, -4, 0), width=8, height=8)
    with pytest.raises(strata.InputError, match="along the line of sight"):
        r.render(eye=(0, -4, 0), target=(0, 0, 0), up=(0, 1, 0), width=8, height=8)
    with pytest.raises(strata.InputError, match="not both"):
        r.render(az=10, eye=(0, -4, 0), target=(0, 0, 0), width=8, height=8)


def test_picking_every_layer_and_rectangles(device):
    g = strata.load("builtin:spheres:16")
    p = strata.Picker(device)
    p.set_geometry(g)
    r = strata.Renderer(device, "ppll", depth_complexity=True)
    r.set_geometry(g)
    r.render(width=64, height=64)
    counts = r.depth_complexity
    y, x = np.unravel_index(int(np.argmax(counts)), counts.shape)
    hit = p.pick([(int(x), int(y)), (-1, 5)], all_layers=True, width=64, height=64)
    layers = hit[0]["layers"]
    assert hit[0]["hit"] and len(layers) == counts[y, x]
    depths = [layer["depth"] for layer in layers]
    assert depths == sorted(depths) and layers[0]["depth"] == hit[0]["depth"]
    assert layers[0]["transmittance"] == 1.0 and layers[-1]["transmittance"] < 1.0
    assert hit[1] == {"hit": False, "layers": []}
    front_only = p.pick([(int(x), int(y))], width=64, height=64)[0]
    assert "layers" not in front_only and front_only["object"] == layers[0]["object"]
    objects = p.objects_in_rect((0, 0, 63, 63), width=64, height=64)
    ids = [o["object"] for o in objects]
    assert ids == sorted(set(ids)) and layers[0]["object"] in ids
    assert all(isinstance(o["name"], str) for o in objects)
    with pytest.raises(strata.InputError):
        p.objects_in_rect((10, 10, 5, 5), width=64, height=64)
    with pytest.raises(strata.InputError, match="Picker.pick: no geometry"):
        strata.Picker(device).pick([(0, 0)])


def test_save_image(device, tmp_path):
    r = strata.Renderer(device, "ppll")
    r.set_geometry(strata.load("builtin:demo"))
    image = r.render(width=40, height=30)
    path = tmp_path / "a.png"
    strata.save_image(str(path), image)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    strata.save_image(str(tmp_path / "rgb.png"), image[..., :3])
    with pytest.raises(strata.InputError, match="uint8"):
        strata.save_image(str(tmp_path / "b.png"), image.astype(np.float32))
    with pytest.raises(strata.InputError, match="no/such/folder"):
        strata.save_image("/no/such/folder/c.png", image)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_reprs_and_docs(device):
    g = strata.load("builtin:demo")
    assert repr(g).startswith("<strata.Geometry 'builtin:demo': ") and "triangles" in repr(g)
    assert repr(device).startswith("<strata.Device '")
    r = strata.Renderer(device, "cells")
    r.set_geometry(g)
    assert repr(r).startswith("<strata.Renderer 'cells' on '") and "builtin:demo" in repr(r)
    assert r.geometry is not None and r.geometry.source == "builtin:demo"
    assert repr(strata.Picker(device)) == "<strata.Picker>"
    # Every parameter of every call is explained in its docstring (what pydoc shows).
    import inspect
    import re as regex
    calls = [strata.load, strata.from_arrays, strata.save_image, strata.compare,
             strata.Renderer.__init__,
             strata.Renderer.render, strata.Renderer.set_geometry, strata.Picker.pick,
             strata.Picker.objects_in_rect, strata.Picker.set_geometry, strata.Picker.__init__,
             strata.Device.__init__]
    for call in calls:
        doc = call.__doc__
        signature = doc.splitlines()[0] if doc else ""
        names = [n for n in regex.findall(r"(\w+): ", signature.split("(", 1)[-1]) if n != "self"]
        body = "\n".join(doc.splitlines()[1:])
        for name in names:
            assert regex.search(rf"\b{name}\b[^\n]*:", body), (call.__qualname__, name, body)


def test_compare_gives_the_error_map(device):
    g = strata.load(os.path.join(MODELS, "teapot.obj"))
    cells, _ = render(device, "cells", g, az=35, el=25)
    reference, _ = render(device, "embree", g, az=35, el=25)
    same = strata.compare(reference, reference)
    assert same["psnr"] == float("inf") and same["max_abs"] == 0 and same["within_2"] == 1.0
    c = strata.compare(cells, reference)
    assert c["within_2"] >= 0.995 and c["pixels"] == SIZE * SIZE
    error = c["error"]
    assert error.shape == (SIZE, SIZE) and error.dtype == np.uint8
    expected = np.abs(cells[..., :3].astype(int) - reference[..., :3].astype(int)).max(axis=2)
    assert np.array_equal(error, expected) and int(error.max()) == c["max_abs"]
    assert abs(float((error <= 2).mean()) - c["within_2"]) < 1e-9
    assert c["difference"].shape == (SIZE, SIZE, 4)
    with pytest.raises(strata.InputError, match="reference"):
        strata.compare(cells, reference[..., 0])
    with pytest.raises(strata.InputError):
        strata.compare(cells, reference[:10])


def test_approximate_method_options(device):
    g = strata.load(os.path.join(MODELS, "teapot.obj"))
    reference, _ = render(device, "embree", g, az=35, el=25)

    def stochastic(**options):
        r = strata.Renderer(device, "stochastic", **options)
        r.set_geometry(g)
        return r.render(width=SIZE, height=SIZE, az=35, el=25)

    few, many = stochastic(samples=4, seed=3), stochastic(samples=64, seed=3)
    assert np.array_equal(few, stochastic(samples=4, seed=3))
    assert not np.array_equal(few, stochastic(samples=4, seed=4))
    assert strata.compare(many, reference)["psnr"] > strata.compare(few, reference)["psnr"]
    assert not np.array_equal(few, stochastic(samples=4, seed=3, alpha_correction=False))
    with pytest.raises(strata.InputError, match="samples"):
        stochastic(samples=0)
    def abuffer(tail):
        r = strata.Renderer(device, "abuffer", k=1, tail=tail)
        r.set_geometry(g)
        return r.render(width=SIZE, height=SIZE, az=35, el=25), r.stats

    dropped, dropped_stats = abuffer("drop")
    blended, blended_stats = abuffer("blend")
    assert dropped_stats["fragments_lost"] > 0 and blended_stats["fragments_lost"] == 0
    assert strata.compare(blended, reference)["psnr"] > strata.compare(dropped, reference)["psnr"]
    with pytest.raises(strata.InputError, match="tail"):
        abuffer("keep")
    for method in ("adaptive", "mlab", "hybrid"):
        r = strata.Renderer(device, method, k=2)
        r.set_geometry(g)
        image = r.render(width=SIZE, height=SIZE, az=35, el=25)
        assert strata.compare(image, reference)["psnr"] > 20, method


def test_compare_agrees_with_scikit_image(device):
    metrics = pytest.importorskip("skimage.metrics")
    g = strata.load(os.path.join(MODELS, "cow.obj"))
    reference, _ = render(device, "embree", g, az=35, el=25)
    rng = np.random.default_rng(5)
    noise = np.clip(reference.astype(int) + rng.integers(-40, 41, reference.shape), 0, 255)
    candidates = [render(device, m, g, az=35, el=25)[0] for m in ("wboit", "stochastic", "cells")]
    for image in candidates + [noise.astype(np.uint8)]:
        c = strata.compare(image, reference)
        a, b = image[..., :3], reference[..., :3]
        ssim = metrics.structural_similarity(a, b, channel_axis=2, gaussian_weights=True, sigma=1.5,
                                             use_sample_covariance=False, data_range=255)
        assert abs(c["ssim"] - ssim) < 1e-6
        assert c["ssim_map"].shape == (SIZE, SIZE)
        assert abs(float(c["ssim_map"][5:-5, 5:-5].mean()) - c["ssim"]) < 1e-5
        if c["psnr"] != float("inf"):
            psnr = metrics.peak_signal_noise_ratio(b, a, data_range=255)
            assert abs(c["psnr"] - psnr) < 1e-6
            assert abs(c["rmse"] - float(np.sqrt(((a.astype(float) - b) ** 2).mean()))) < 1e-6
    assert strata.compare(reference[:8, :8], reference[:8, :8])["ssim"] is None
