// `import strata`: devices, geometry from files or NumPy arrays, renderers by method name
// (the Embree reference included), picking, images saved. Images come back as HxWx4 uint8
// arrays, statistics as dicts; every error is a strata.Error: strata.InputError (a ValueError)
// for bad input, strata.DeviceError (a RuntimeError) for a device or driver that fails,
// strata.OutOfMemoryError (a MemoryError) for memory that cannot be had. The GIL is released
// while rendering; calls on one Renderer from several threads are serialised
// (include/strata/strata.h). The stubs in strata.pyi mirror this file: keep them together.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <optional>

#include "strata/strata.h"

namespace py = pybind11;
using namespace pybind11::literals;  // "key"_a = value: dicts built by keyword

namespace {

py::object parseJson(const std::string& text) {
  return py::module_::import("json").attr("loads")(text);
}

py::dict methodDict(const strata::MethodInfo& m) {
  return py::dict("name"_a = m.name, "summary"_a = m.summary, "exact"_a = m.exact,
                  "opencl"_a = m.opencl, "takes_k"_a = m.takes_k,
                  "translucency"_a = m.translucency);
}

strata::Effect parseEffect(const std::string& name) {
  if (name == "transparency") return strata::Effect::Transparency;
  if (name == "translucency") return strata::Effect::Translucency;
  throw strata::Error("effect: unknown effect '" + name + "' (known: transparency, translucency)");
}

std::string quoted(const std::string& s) { return std::string(py::repr(py::str(s))); }

// A 2-D array of `columns` columns, converted to a contiguous array of T; anything else is a
// strata::Error naming the argument.
template <typename T>
py::array_t<T, py::array::c_style> matrix(const py::handle& obj, py::ssize_t columns,
                                          const char* what) {
  py::array a = py::array::ensure(obj);
  if (!a) throw strata::Error(std::string(what) + ": not an array");
  if (a.ndim() != 2 || a.shape(1) != columns)
    throw strata::Error(std::string(what) + ": expected shape (N, " + std::to_string(columns) +
                        "), got " +
                        std::string(py::str(py::tuple(
                            py::cast(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()))))));
  if (a.size() == 0) throw strata::Error(std::string(what) + ": empty");
  const char kind = a.dtype().kind();
  if (kind != 'b' && kind != 'i' && kind != 'u' && kind != 'f')
    throw strata::Error(std::string(what) + ": expected an array of numbers, got dtype " +
                        std::string(py::str(a.dtype())));
  // The library takes at most 2^30 - 1 rows (vertices or triangles); checked before a copy
  // is made (a broadcast array may claim far more rows than memory holds).
  constexpr py::ssize_t kMaxRows = py::ssize_t(UINT32_MAX / 4);
  if (a.shape(0) > kMaxRows)
    throw strata::Error(std::string(what) + ": " + std::to_string(a.shape(0)) +
                        " rows, more than the " + std::to_string(kMaxRows) + " strata takes");
  auto converted = py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!converted)  // numpy could not make the contiguous copy (memory)
    throw strata::OutOfMemory(std::string(what) + ": out of memory converting the array");
  return converted;
}

strata::Geometry fromArraysUnchecked(const py::object& positions, const py::object& indices,
                                     const py::object& colors, float alpha) {
  auto p = matrix<float>(positions, 3, "positions");
  // Indices: integers only; negative ones are refused before the conversion to uint32.
  py::array raw = py::array::ensure(indices);
  if (!raw || (raw.dtype().kind() != 'i' && raw.dtype().kind() != 'u'))
    throw strata::Error("indices: expected an integer array of shape (M, 3)");
  auto wide = matrix<int64_t>(indices, 3, "indices");
  std::vector<uint32_t> idx(size_t(wide.size()));
  const int64_t* w = wide.data();
  for (size_t i = 0; i < idx.size(); ++i) {
    if (w[i] < 0 || w[i] > int64_t(UINT32_MAX))
      throw strata::Error("indices: " + std::to_string(w[i]) + " is not a vertex index");
    idx[i] = uint32_t(w[i]);
  }
  py::array_t<float, py::array::c_style> c;
  if (!colors.is_none()) {
    c = matrix<float>(colors, 4, "colors");
    if (c.shape(0) != wide.shape(0))
      throw strata::Error("colors: one RGBA row per triangle expected (" +
                          std::to_string(wide.shape(0)) + ")");
  }
  return strata::Geometry::fromArrays(p.data(), size_t(p.shape(0)), idx.data(),
                                      size_t(wide.shape(0)), colors.is_none() ? nullptr : c.data(),
                                      alpha);
}

strata::Geometry fromArrays(const py::object& positions, const py::object& indices,
                            const py::object& colors, float alpha) {
  try {
    return fromArraysUnchecked(positions, indices, colors, alpha);
  } catch (const std::bad_alloc&) {  // the copies made here, before the library's own checks
    throw strata::OutOfMemory(
        "geometry arrays: out of memory (the arrays need more memory than "
        "there is)");
  }
}

// The view keywords every render and pick takes, documented once (kViewDoc).
struct ViewArgs {
  std::optional<float> az, el;
  int width = 512, height = 512;
  std::optional<float> distance;
  std::optional<bool> ortho;
  float fov = 40.0f;
  std::optional<float> ortho_height;
  std::optional<std::array<float, 3>> eye, target;
  std::array<float, 3> up{0.0f, 1.0f, 0.0f};
};

const char* const kViewDoc = R"(
The view (keywords, all optional):
    az, el: orbit angles in degrees around the scene's bounding sphere: azimuth about the +Y
        axis (0 looks along -Z, 90 along -X), elevation above the XZ plane (90 looks straight
        down). Without az, el, eye: the scene's own view, as `strata render` without --view
        (builtin:spheres:N along its stack, orthographic; a mesh file at az=30, el=20).
    width, height: image size in pixels.
    distance: the camera's distance in bounding-sphere radii (None: framed to fit).
    ortho: True orthographic, False perspective, None the scene's own projection.
    fov: perspective vertical field of view in degrees (1..179).
    ortho_height: orthographic world height seen (None: the scene's own, else the sphere's).
    eye, target, up: (x, y, z) world coordinates of a look-at camera, instead of az/el: the
        camera at eye looks at target with up pointing up in the image (a Z-up mesh: up=(0,0,1)).
)";

strata::View makeView(const strata::Geometry& g, const ViewArgs& a) {
  strata::View v;
  if (a.eye || a.target) {
    if (!a.eye || !a.target) throw strata::Error("view: eye and target go together");
    if (a.az || a.el || a.distance)
      throw strata::Error("view: give az/el/distance or eye/target, not both");
    v = strata::View::lookAt(a.eye->data(), a.target->data(), a.up.data(), a.width, a.height);
  } else {
    v = g.naturalView(a.width, a.height);
    if (a.az || a.el || a.distance) v.ortho_height = 0.0f;  // a chosen view is framed afresh
    if (a.az) v.azimuth_deg = *a.az;
    if (a.el) v.elevation_deg = *a.el;
    if (a.distance) {
      if (!(*a.distance > 0.0f) || !std::isfinite(*a.distance))
        throw strata::Error("view: distance must be > 0 bounding-sphere radii (None: framed)");
      v.distance = *a.distance;
    }
  }
  v.width = a.width;
  v.height = a.height;
  if (a.ortho) v.orthographic = *a.ortho;
  v.fov_deg = a.fov;
  if (a.ortho_height) {
    if (!(*a.ortho_height > 0.0f) || !std::isfinite(*a.ortho_height))
      throw strata::Error("view: ortho_height must be > 0 world units");
    v.ortho_height = *a.ortho_height;
  }
  return v;
}

// Declares the view keywords of a binding, in ViewArgs' order.
#define STRATA_VIEW_ARGS                                                                     \
  py::kw_only(), py::arg("az") = py::none(), py::arg("el") = py::none(),                     \
      py::arg("width") = 512, py::arg("height") = 512, py::arg("distance") = py::none(),     \
      py::arg("ortho") = py::none(), py::arg("fov") = 40.0f,                                 \
      py::arg("ortho_height") = py::none(), py::arg("eye") = py::none(),                     \
      py::arg("target") = py::none(), py::arg("up") = std::array<float, 3>{0.0f, 1.0f, 0.0f}

ViewArgs viewArgs(std::optional<float> az, std::optional<float> el, int width, int height,
                  std::optional<float> distance, std::optional<bool> ortho, float fov,
                  std::optional<float> ortho_height, std::optional<std::array<float, 3>> eye,
                  std::optional<std::array<float, 3>> target, std::array<float, 3> up) {
  return ViewArgs{az, el, width, height, distance, ortho, fov, ortho_height, eye, target, up};
}

py::array_t<uint8_t> imageArray(const strata::Image& image) {
  py::array_t<uint8_t> a({image.height, image.width, 4});
  std::memcpy(a.mutable_data(), image.rgba.data(), image.rgba.size());
  return a;
}

strata::Image imageFromArray(const py::object& obj, const char* what = "image") {
  py::array a = py::array::ensure(obj);
  if (!a || a.ndim() != 3 || (a.shape(2) != 3 && a.shape(2) != 4) || a.shape(0) == 0 ||
      a.shape(1) == 0)
    throw strata::Error(std::string(what) +
                        ": expected an (height, width, 4) or (height, width, 3) array");
  if (a.dtype().kind() != 'u' || a.dtype().itemsize() != 1)
    throw strata::Error(std::string(what) + ": expected uint8 values (0..255), got dtype " +
                        std::string(py::str(a.dtype())));
  auto c = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>::ensure(a);
  strata::Image image(int(a.shape(1)), int(a.shape(0)));
  const size_t channels = size_t(a.shape(2));
  const uint8_t* src = c.data();
  for (size_t p = 0; p < size_t(image.width) * size_t(image.height); ++p)
    for (size_t ch = 0; ch < 4; ++ch)
      image.rgba[4 * p + ch] = ch < channels ? src[channels * p + ch] : 255;
  return image;
}

py::dict layerDict(const strata::PickLayer& l) {
  return py::dict("object"_a = l.object, "triangle"_a = l.triangle, "name"_a = l.name,
                  "depth"_a = l.depth,
                  "position"_a = py::make_tuple(l.position[0], l.position[1], l.position[2]),
                  "normal"_a = py::make_tuple(l.normal[0], l.normal[1], l.normal[2]),
                  "front_facing"_a = l.front_facing, "opacity"_a = l.opacity,
                  "transmittance"_a = l.transmittance);
}

// A renderer, its geometry (for the scene's own view) and the statistics of its last frame.
struct PyRenderer {
  strata::Renderer renderer;
  std::string device_label;
  std::optional<strata::Geometry> geometry;
  py::object stats = py::none();
  py::object depth_complexity = py::none();

  py::array_t<uint8_t> render(const ViewArgs& args) {
    if (!geometry)
      throw strata::Error(
          "Renderer.render: no geometry: call set_geometry(strata.load(...) or "
          "strata.from_arrays(...)) first");
    const strata::View view = makeView(*geometry, args);
    strata::Frame f;
    {
      py::gil_scoped_release release;
      f = renderer.render(view);
    }
    stats = parseJson(f.stats_json);
    depth_complexity = py::none();
    if (!f.depth_complexity.empty()) {
      py::array_t<uint32_t> d({f.image.height, f.image.width});
      std::memcpy(d.mutable_data(), f.depth_complexity.data(), f.depth_complexity.size() * 4);
      depth_complexity = d;
    }
    return imageArray(f.image);
  }
};

struct PyPicker {
  strata::Picker picker;
  std::optional<strata::Geometry> geometry;

  const strata::Geometry& scene(const char* call) const {
    if (!geometry)
      throw strata::Error(std::string("Picker.") + call +
                          ": no geometry: call set_geometry(strata.load(...)) first");
    return *geometry;
  }
};

}  // namespace

PYBIND11_MODULE(strata, m) {
  m.doc() = R"(strata: exact order-independent transparency of triangle meshes, rendered by OpenCL
kernels on any OpenCL device (a GPU, or PoCL on a CPU) and checked against an Embree reference.

    import strata
    device = strata.Device()                        # a GPU, else the first OpenCL device
    mesh = strata.load("bunny.obj")                 # or builtin:NAME, or strata.from_arrays(...)
    r = strata.Renderer(device, "cells")            # any name of strata.methods()
    r.set_geometry(mesh)                            # uploads and prepares once
    image = r.render(az=30, el=20, width=512, height=512)   # (512, 512, 4) uint8 RGBA
    strata.save_image("bunny.png", image)
    r.stats["frame_ms"]["median"], r.stats["fragments"]

Conventions: world units are the mesh's; angles are degrees; images are (height, width, 4)
uint8 RGBA, top row first, composited over the background (checker or a colour), opaque, not
premultiplied. Every error is a strata.Error.)";
  m.attr("__version__") = STRATA_VERSION;
  // strata.Error is the base of every error strata raises. Bad input (a file, an array, an
  // option) is a strata.InputError, also a ValueError; a device or driver that fails is a
  // strata.DeviceError, also a RuntimeError; memory that cannot be had, host or device, a
  // strata.OutOfMemoryError, also a MemoryError.
  {
    auto make = [&m](const char* name, py::tuple bases, const char* doc) {
      PyObject* type = PyErr_NewExceptionWithDoc(
          (std::string("strata.") + name).c_str(), doc, bases.ptr(), nullptr);
      if (!type) throw py::error_already_set();
      m.attr(name) = py::reinterpret_steal<py::object>(type);
      return py::handle(type);  // the module keeps it alive
    };
    static py::handle error = make("Error", py::make_tuple(py::handle(PyExc_Exception)),
                                   "Every error strata raises; the message is one line naming "
                                   "the file or the call and the problem.");
    static py::handle input_error =
        make("InputError", py::make_tuple(error, py::handle(PyExc_ValueError)),
             "Bad input: a file, an array, a method name, an option or a view.");
    static py::handle device_error =
        make("DeviceError", py::make_tuple(error, py::handle(PyExc_RuntimeError)),
             "The OpenCL device or its driver failed: no device, a missing extension, kernels "
             "that do not build, a call that fails.");
    static py::handle out_of_memory =
        make("OutOfMemoryError", py::make_tuple(error, py::handle(PyExc_MemoryError)),
             "Memory that cannot be had, host or device; the message names what did not fit.");
    py::register_exception_translator([](std::exception_ptr p) {
      try {
        if (p) std::rethrow_exception(p);
      } catch (const strata::OutOfMemory& e) {
        PyErr_SetString(out_of_memory.ptr(), e.what());
      } catch (const strata::DeviceError& e) {
        PyErr_SetString(device_error.ptr(), e.what());
      } catch (const strata::Error& e) {
        PyErr_SetString(input_error.ptr(), e.what());
      }
    });
  }

  m.def(
      "methods",
      [] {
        py::list out;
        for (const strata::MethodInfo& i : strata::methods()) out.append(methodDict(i));
        return out;
      },
      R"(Every rendering method, as a list of dicts:
    name: what Renderer(device, method) takes ("cells", "ppll", ..., "embree");
    summary: one line;
    exact: equal to the Embree reference within 2/255 (budgeted methods while k >= depth);
    opencl: False for the CPU reference ("embree");
    takes_k: reads the Renderer's k (fragments kept per pixel);
    translucency: renders effect="translucency" too.)");
  m.def(
      "devices",
      [] {
        py::list out;
        for (const strata::DeviceDescription& d : strata::Device::list()) {
          out.append(py::dict("index"_a = d.index, "name"_a = d.name, "platform"_a = d.platform,
                              "driver"_a = d.driver, "gpu"_a = d.gpu));
        }
        return out;
      },
      R"(The OpenCL devices, as a list of dicts: index (what Device takes), name, platform,
driver, gpu (True for a GPU).)");

  py::class_<strata::Device>(m, "Device", "An OpenCL device.")
      .def(py::init([](const std::string& spec, const std::string& atomics) {
             return strata::Device::open(spec, atomics);
           }),
           py::arg("spec") = "", py::arg("atomics") = "auto",
           R"(Opens an OpenCL device.

spec: "" for the first GPU, else the first device; an index from strata.devices() ("0"); or a
    case-insensitive part of the device or platform name ("pocl", "nvidia").
atomics: "auto" (64-bit atomics where the device has them), "64", or "32": the path without
    64-bit atomics (every method's serial tile kernels; the same images and counts).
Raises strata.DeviceError when no device can be opened, strata.InputError for a spec that
names none or an unknown atomics choice.)")
      .def_property_readonly("label", &strata::Device::label,
                             "\"NAME (PLATFORM, DRIVER)\" of the device.")
      .def_property_readonly("int64_atomics", &strata::Device::int64Atomics,
                             "Whether the device was opened with 64-bit atomics.")
      .def("__repr__", [](const strata::Device& d) {
        return "<strata.Device " + quoted(d.label()) + ">";
      });

  py::class_<strata::Geometry>(
      m, "Geometry",
      "A validated triangle scene, immutable: made by strata.load or strata.from_arrays and "
      "shared by any number of renderers and pickers.")
      .def_property_readonly("triangle_count", &strata::Geometry::triangleCount,
                             "Triangles kept (zero-area and non-finite ones are dropped).")
      .def_property_readonly(
          "vertex_count", &strata::Geometry::vertexCount,
          "Vertices of every mesh together (from_arrays with colors: a vertex counts once per "
          "colour among the triangles that use it, as each colour is a mesh of its own; 0 for "
          "an octree scene file, which stays on disk).")
      .def_property_readonly("source", &strata::Geometry::source,
                             "Where it came from: the file name, builtin:NAME, or \"arrays\".")
      .def_property_readonly(
          "bounding_sphere",
          [](const strata::Geometry& g) {
            float c[3], r = 0.0f;
            g.boundingSphere(c, &r);
            return py::make_tuple(py::make_tuple(c[0], c[1], c[2]), r);
          },
          "((x, y, z), radius) of the kept triangles, in world units; orbit views circle it.")
      .def(
          "natural_view",
          [](const strata::Geometry& g) {
            const strata::View v = g.naturalView();
            return py::dict(
                "az"_a = v.azimuth_deg, "el"_a = v.elevation_deg,
                "distance"_a = v.distance > 0.0f ? py::cast(v.distance) : py::none(),
                "ortho"_a = v.orthographic,
                "ortho_height"_a = v.ortho_height > 0.0f ? py::cast(v.ortho_height) : py::none());
          },
          "The scene's own view, what render() shows without az, el or eye: a dict of az, el, "
          "distance, ortho and ortho_height, the keywords render() takes.")
      .def("__repr__", [](const strata::Geometry& g) {
        return "<strata.Geometry " + quoted(g.source()) + ": " +
               std::to_string(g.triangleCount()) + " triangles, " +
               std::to_string(g.vertexCount()) + " vertices>";
      });
  m.def("load", &strata::Geometry::load, py::arg("path"), py::arg("alpha") = -1.0f,
        R"(Loads a scene.

path: a mesh file (OBJ with MTL materials and textures, PLY, OFF, STL, glTF 2.0 / GLB,
    glTF 1.0), an octree scene file (FILE.octree from `strata prep SCENE --octree`), or a
    built-in scene: builtin:demo, builtin:spheres:N (N depth layers), builtin:crowd:N,
    builtin:textured:N, builtin:hairball:N, builtin:city:N, builtin:shells:N, builtin:soup:N.
alpha: an opacity in 0..1 for every material; negative keeps the file's own.
Raises strata.InputError naming the file and the problem.)");
  m.def("from_arrays", &fromArrays, py::arg("positions"), py::arg("indices"),
        py::arg("colors") = py::none(), py::arg("alpha") = -1.0f,
        R"(One mesh from NumPy arrays.

positions: (N, 3) vertex positions, any real dtype (converted to float32), finite.
indices: (M, 3) integer vertex indices, counter-clockwise seen from the front.
colors: optional (M, 4) RGBA per triangle in 0..1, the 4th being the opacity; each distinct
    colour becomes a material (and a mesh of its own, which is why vertex_count may grow).
alpha: without colors, the opacity of the grey material (negative: 0.5); with colors, a
    value in 0..1 replaces every triangle's opacity.
Zero-area triangles are dropped as the file loaders drop them. Raises strata.InputError
naming the argument.)");
  m.def(
      "save_image",
      [](const std::string& path, const py::object& image) {
        const strata::Image im = imageFromArray(image);
        py::gil_scoped_release release;
        strata::saveImage(path, im);
      },
      py::arg("path"), py::arg("image"),
      R"(Writes an image file.

path: the file; its extension chooses the format (.png, and what the image library knows).
    Written to a temporary name beside it and renamed, so a failure leaves what was there.
image: (height, width, 4) or (height, width, 3) uint8 array, as render() returns.)");

  m.def(
      "compare",
      [](const py::object& image, const py::object& reference) {
        const strata::Image a = imageFromArray(image, "image");
        const strata::Image b = imageFromArray(reference, "reference");
        const strata::ImageDiff d = strata::compareImages(a, b);
        py::array_t<uint8_t> error({a.height, a.width});
        uint8_t* e = error.mutable_data();
        for (size_t p = 0; p < size_t(a.width) * size_t(a.height); ++p) {
          int worst = 0;
          for (size_t c = 0; c < 3; ++c)
            worst = std::max(worst, std::abs(int(a.rgba[4 * p + c]) - int(b.rgba[4 * p + c])));
          e[p] = uint8_t(worst);
        }
        py::object ssim = py::none(), ssim_map = py::none();
        if (a.width >= strata::kSsimMinSize && a.height >= strata::kSsimMinSize) {
          std::vector<float> map;
          ssim = py::float_(strata::structuralSimilarity(a, b, &map));
          py::array_t<float> m({a.height, a.width});
          std::copy(map.begin(), map.end(), m.mutable_data());
          ssim_map = m;
        }
        return py::dict("psnr"_a = d.psnr, "rmse"_a = d.rmse, "ssim"_a = ssim,
                        "max_abs"_a = d.max_abs, "mean_abs"_a = d.mean_abs,
                        "within_1"_a = d.within_1, "within_2"_a = d.within_2,
                        "pixels"_a = d.pixels, "error"_a = error, "ssim_map"_a = ssim_map,
                        "difference"_a = imageArray(strata::differenceImage(a, b)));
      },
      py::arg("image"), py::arg("reference"),
      R"(How far an image is from a reference, as `strata diff` measures it (RGB; alpha ignored).

image, reference: (height, width, 4) or (height, width, 3) uint8 arrays of one size.
Returns a dict: psnr (dB; inf when identical), rmse (root mean square channel difference in
0..255), ssim (structural similarity, Wang et al. 2004, as scikit-image's structural_similarity
with gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=255; None under
11 pixels a side) and ssim_map (each pixel's SSIM over its channels, an (height, width) float32
array, or None), max_abs and mean_abs (channel difference in 0..255), within_1 and within_2 (the share of pixels whose channels all differ by at most 1 or
2; the exact methods reach 0.995 within 2 against "embree"), pixels, error (an (height, width)
uint8 array: each pixel's largest channel difference, the error map) and difference (the
difference image, |image - reference| x 8, as `strata diff --out` writes it).)");

  const std::string render_doc =
      std::string(R"(Renders one view of the geometry.

Returns an (height, width, 4) uint8 RGBA array; the frame's statistics are then in .stats and,
with depth_complexity=True, the fragments per pixel in .depth_complexity.
)") + kViewDoc;

  py::class_<PyRenderer>(m, "Renderer",
                         "A renderer of one method: set_geometry once, then render many views.")
      .def(py::init([](const strata::Device& device, const std::string& method,
                       const std::string& effect, int k, float sigma, int frames, float orbit,
                       const std::string& batch, const std::string& sort, const std::string& atlas,
                       const std::string& decompose, const std::string& cache_dir,
                       bool depth_complexity, const std::string& octree_variant, uint32_t leaf_tris,
                       uint32_t octree_k, double memory_budget_mb, const std::string& tile_kernels,
                       const std::optional<std::array<float, 3>>& background,
                       const std::string& wboit_weight, uint32_t samples, uint32_t seed,
                       bool alpha_correction, const std::string& tail) {
             strata::RenderOptions o;
             o.effect = parseEffect(effect);
             o.k = k;
             o.sigma = sigma;
             o.frames = frames;
             o.orbit_deg = orbit;
             o.tile_kernels = strata::parseTileKernels(tile_kernels);
             o.wboit.weight = strata::parseWboitWeight(wboit_weight);
             o.stochastic.samples = samples;
             o.stochastic.seed = seed;
             o.stochastic.alpha_correction = alpha_correction;
             o.abuffer.tail = strata::parseAbufferTail(tail);
             o.batch = strata::parseBatch(batch);
             o.sort = strata::parseDrawSort(sort);
             o.atlas = strata::parseAtlasChoice(atlas);
             o.decompose = strata::parseDecomposeMode(decompose);
             o.cell_cache_dir = cache_dir;
             o.capture_depth_complexity = depth_complexity;
             o.octree.variant = octree_variant;
             o.octree.leaf_triangles = leaf_tris;
             o.octree.k = octree_k;
             if (background) {
               for (int i = 0; i < 3; ++i) {
                 const float c = (*background)[size_t(i)];
                 if (!(c >= 0.0f && c <= 1.0f))
                   throw strata::Error("background: an (r, g, b) colour in 0..1 expected");
                 o.background_rgb[i] = c;
               }
               o.checker_background = false;
             }
             if (!(memory_budget_mb >= 0.0))
               throw strata::Error("memory_budget_mb must be a number of megabytes >= 0");
             o.memory_budget = uint64_t(memory_budget_mb * 1024.0 * 1024.0);
             return new PyRenderer{strata::Renderer(device, method, o), device.label()};
           }),
           py::arg("device"), py::arg("method"), py::arg("effect") = "transparency",
           py::arg("k") = 16, py::arg("sigma") = -1.0f, py::arg("frames") = 1,
           py::arg("orbit") = 0.0f, py::arg("batch") = "static", py::arg("sort") = "none",
           py::arg("atlas") = "packed", py::arg("decompose") = "strict",
           py::arg("cache_dir") = "", py::arg("depth_complexity") = false,
           py::arg("octree_variant") = "kbuffer",
           py::arg("leaf_tris") = strata::OctreeMethodOptions{}.leaf_triangles,
           py::arg("octree_k") = strata::OctreeMethodOptions{}.k, py::arg("memory_budget_mb") = 0.0,
           py::arg("tile_kernels") = "auto", py::arg("background") = py::none(),
           py::arg("wboit_weight") = "eq10",
           py::arg("samples") = strata::StochasticOptions{}.samples, py::arg("seed") = 0u,
           py::arg("alpha_correction") = true, py::arg("tail") = "drop",
           R"(A renderer of one method on one device.

device: a strata.Device.
method: a name from strata.methods(): "cells" (convex cells in visibility order), "octree",
    "ppll" (per-pixel linked lists), "abuffer", "mdts", "mdts32" (fixed-k A-buffers), "dp",
    "ddp", "bucket" (peeling), "opaque" (the nearest surface only), "embree" (the CPU
    reference), ...
effect: "transparency" (flat colours composited front to back by opacity) or "translucency"
    (Beer-Lambert absorption inside closed meshes; methods with translucency=True).
k: fragments kept per pixel by the fixed-k methods (takes_k=True; mlab and hybrid: their
    layers, past which mlab merges and hybrid averages; adaptive: the nodes of its visibility
    function); exact while k >= depth.
sigma: translucency's absorption per world unit (negative: 1 / bounding-sphere radius).
frames: frames rendered per render() call; stats["frame_ms"] is over them.
orbit: degrees of azimuth the camera turns per frame within one render() (a moving camera).
batch: "none", "static", "instanced" or "auto": how instances are drawn.
sort: "none", "material", "depth", "gray" or "key": the draw order of instances.
atlas: "packed", "uniform" or "off": how textures share device memory.
decompose: cells: "strict" (exact order) or "paper" (as published).
cache_dir: where cells and octree keep their preprocessing ("": $XDG_CACHE_HOME/strata).
depth_complexity: also count the fragments per pixel (.depth_complexity after render()).
octree_variant: octree: "kbuffer", "blocks-histogram", "blocks", "histogram" or "dp".
leaf_tris: octree: the triangle limit of a leaf.
octree_k: octree kbuffer: fragments per pixel taken per walk (1..64).
memory_budget_mb: device megabytes a frame may use (0: no bound); octree keeps within it,
    other methods raise strata.OutOfMemoryError with what they needed.
tile_kernels: "auto", "group" (GPU-style work-groups) or "serial" (one item per tile, what
    suits a CPU); the same images.
background: an (r, g, b) colour in 0..1 behind the scene (None: a grey checkerboard).
wboit_weight: wboit: the weight function of McGuire and Bavoil's equations, "eq7", "eq8" or
    "eq9" (of the view distance in scene units) or "eq10" (of the depth-buffer value).
samples: stochastic: coverage samples per pixel, 1..64 (noise falls as 1 / sqrt(samples)).
seed: stochastic: the seed of the random coverage masks (a seed gives one image).
alpha_correction: stochastic: the paper's alpha correction (False: the plain estimator, whose
    expectation is the exact image).
tail: abuffer: "drop" (fragments past k lost and counted, as published) or "blend" (blended
    order-independently into a tail behind the k sorted ones).
Raises strata.InputError for an unknown method or option.)")
      .def(
          "set_geometry",
          [](PyRenderer& r, const strata::Geometry& g) {
            r.renderer.setGeometry(g);
            r.geometry = g;
          },
          py::arg("geometry"),
          "Sets the scene.\n\ngeometry: a strata.Geometry; the next render() uploads and "
          "prepares it (convex cells, octree, atlas), later ones reuse that.")
      .def(
          "render",
          [](PyRenderer& r, std::optional<float> az, std::optional<float> el, int width,
             int height, std::optional<float> distance, std::optional<bool> ortho, float fov,
             std::optional<float> ortho_height, std::optional<std::array<float, 3>> eye,
             std::optional<std::array<float, 3>> target, std::array<float, 3> up) {
            return r.render(viewArgs(az, el, width, height, distance, ortho, fov, ortho_height,
                                     eye, target, up));
          },
          STRATA_VIEW_ARGS, render_doc.c_str())
      .def_readonly("stats", &PyRenderer::stats,
                    "The last frame's statistics, a dict as `strata render --stats` writes: "
                    "frame_ms (median, min, max), fragments, max_depth_complexity, "
                    "device_bytes, stage_ms, and the method's own; None before a render.")
      .def_readonly("depth_complexity", &PyRenderer::depth_complexity,
                    "Fragments per pixel of the last frame, an (height, width) uint32 array "
                    "(with depth_complexity=True; else None).")
      .def_property_readonly(
          "method", [](const PyRenderer& r) { return methodDict(r.renderer.method()); },
          "The method, a dict as strata.methods() lists it.")
      .def_property_readonly(
          "geometry", [](const PyRenderer& r) { return r.geometry; },
          "The geometry set, or None.")
      .def("__repr__", [](const PyRenderer& r) {
        return "<strata.Renderer " + quoted(r.renderer.method().name) + " on " +
               quoted(r.device_label) +
               (r.geometry ? ", geometry " + quoted(r.geometry->source()) : std::string()) + ">";
      });

  const std::string pick_doc = std::string(R"(What is under pixels of a view.

pixels: (x, y) pairs, 0, 0 the top-left pixel.
all_layers: also list every fragment under each pixel, front to back.
Returns one dict per pixel, in the order given: hit (False: background or outside the image)
and, for a hit, the front fragment's object (the instance's id), name, triangle, depth (along
the view axis), position and normal (world), front_facing, opacity and transmittance (the
light the fragments in front let through); with all_layers, "layers": a list of such dicts.
)") + kViewDoc;
  const std::string rect_doc = std::string(R"(The objects seen in a rectangle of a view.

rect: (x0, y0, x1, y1), inclusive pixel bounds inside the image.
Returns the distinct objects front-most at some pixel of it, ascending by id: dicts of object
and name.
)") + kViewDoc;

  py::class_<PyPicker>(m, "Picker",
                       "ID picking: which object and triangle is under a pixel, and every "
                       "fragment behind it; the same rasterization as the renderers.")
      .def(py::init([](const strata::Device& device) {
             return new PyPicker{strata::Picker(device), std::nullopt};
           }),
           py::arg("device"), "A picker.\n\ndevice: a strata.Device.")
      .def(
          "set_geometry",
          [](PyPicker& p, const strata::Geometry& g) {
            p.picker.setGeometry(g);
            p.geometry = g;
          },
          py::arg("geometry"), "Sets the scene to pick in.\n\ngeometry: a strata.Geometry.")
      .def(
          "pick",
          [](PyPicker& p, const std::vector<std::pair<int, int>>& pixels, bool all_layers,
             std::optional<float> az, std::optional<float> el, int width, int height,
             std::optional<float> distance, std::optional<bool> ortho, float fov,
             std::optional<float> ortho_height, std::optional<std::array<float, 3>> eye,
             std::optional<std::array<float, 3>> target, std::array<float, 3> up) {
            const strata::View view =
                makeView(p.scene("pick"), viewArgs(az, el, width, height, distance, ortho, fov,
                                                   ortho_height, eye, target, up));
            std::vector<strata::PickHit> hits;
            {
              py::gil_scoped_release release;
              hits = p.picker.pick(view, pixels, all_layers);
            }
            py::list out;
            for (const strata::PickHit& h : hits) {
              py::dict d = h.hit ? layerDict(h) : py::dict();
              d["hit"] = h.hit;
              if (all_layers) {
                py::list layers;
                for (const strata::PickLayer& l : h.layers) layers.append(layerDict(l));
                d["layers"] = layers;
              }
              out.append(d);
            }
            return out;
          },
          py::arg("pixels"), py::arg("all_layers") = false, STRATA_VIEW_ARGS, pick_doc.c_str())
      .def(
          "objects_in_rect",
          [](PyPicker& p, const std::array<int, 4>& rect, std::optional<float> az,
             std::optional<float> el, int width, int height, std::optional<float> distance,
             std::optional<bool> ortho, float fov, std::optional<float> ortho_height,
             std::optional<std::array<float, 3>> eye, std::optional<std::array<float, 3>> target,
             std::array<float, 3> up) {
            const strata::View view =
                makeView(p.scene("objects_in_rect"),
                         viewArgs(az, el, width, height, distance, ortho, fov, ortho_height, eye,
                                  target, up));
            std::vector<strata::PickedObject> objects;
            {
              py::gil_scoped_release release;
              objects = p.picker.objectsInRect(view, rect[0], rect[1], rect[2], rect[3]);
            }
            py::list out;
            for (const strata::PickedObject& o : objects) {
              out.append(py::dict("object"_a = o.object, "name"_a = o.name));
            }
            return out;
          },
          py::arg("rect"), STRATA_VIEW_ARGS, rect_doc.c_str())
      .def_property_readonly(
          "geometry", [](const PyPicker& p) { return p.geometry; }, "The geometry set, or None.")
      .def("__repr__", [](const PyPicker& p) {
        return std::string("<strata.Picker") +
               (p.geometry ? " geometry " + quoted(p.geometry->source()) : std::string()) + ">";
      });
}
