// `import strata`: devices, geometry from files or NumPy arrays, renderers by method name
// (the Embree reference included), picking. Images come back as HxWx4 uint8 arrays, statistics
// as dicts; every error is a strata.Error: strata.InputError (a ValueError) for bad input,
// strata.DeviceError (a RuntimeError) for a device or driver that fails, strata.OutOfMemoryError
// (a MemoryError) for memory that cannot be had. The GIL is released while rendering; calls on one
// Renderer from several threads are serialised (include/strata/strata.h).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>

#include "strata/strata.h"

namespace py = pybind11;

namespace {

py::object parseJson(const std::string& text) {
  return py::module_::import("json").attr("loads")(text);
}

py::dict methodDict(const strata::MethodInfo& m) {
  py::dict d;
  d["name"] = m.name;
  d["summary"] = m.summary;
  d["exact"] = m.exact;
  d["opencl"] = m.opencl;
  d["takes_k"] = m.takes_k;
  d["translucency"] = m.translucency;
  return d;
}

strata::Effect parseEffect(const std::string& name) {
  if (name == "transparency") return strata::Effect::Transparency;
  if (name == "translucency") return strata::Effect::Translucency;
  throw strata::Error("unknown effect '" + name + "' (known: transparency, translucency)");
}

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

strata::View makeView(float az, float el, int width, int height, float distance, bool ortho,
                      float fov) {
  strata::View v;
  v.azimuth_deg = az;
  v.elevation_deg = el;
  v.width = width;
  v.height = height;
  v.distance = distance;
  v.orthographic = ortho;
  v.fov_deg = fov;
  return v;
}

// A renderer and the statistics of its last frame.
struct PyRenderer {
  strata::Renderer renderer;
  py::object stats = py::none();
  py::object depth_complexity = py::none();

  py::array_t<uint8_t> render(float az, float el, int width, int height, float distance, bool ortho,
                              float fov) {
    const strata::View view = makeView(az, el, width, height, distance, ortho, fov);
    strata::Frame f;
    {
      py::gil_scoped_release release;
      f = renderer.render(view);
    }
    py::array_t<uint8_t> image({f.image.height, f.image.width, 4});
    std::memcpy(image.mutable_data(), f.image.rgba.data(), f.image.rgba.size());
    stats = parseJson(f.stats_json);
    if (!f.depth_complexity.empty()) {
      py::array_t<uint32_t> d({f.image.height, f.image.width});
      std::memcpy(d.mutable_data(), f.depth_complexity.data(), f.depth_complexity.size() * 4);
      depth_complexity = d;
    }
    return image;
  }
};

}  // namespace

PYBIND11_MODULE(strata, m) {
  m.doc() =
      "strata: exact order-independent transparency with OpenCL kernels, checked against Embree";
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
      "Every rendering method: name, summary, exact, opencl, takes_k, translucency.");
  m.def(
      "devices",
      [] {
        py::list out;
        for (const strata::DeviceDescription& d : strata::Device::list()) {
          py::dict e;
          e["index"] = d.index;
          e["name"] = d.name;
          e["platform"] = d.platform;
          e["driver"] = d.driver;
          e["gpu"] = d.gpu;
          out.append(e);
        }
        return out;
      },
      "The OpenCL devices.");

  py::class_<strata::Device>(
      m, "Device",
      "An OpenCL device, chosen by index or name substring ('' : a GPU, else the first).")
      .def(py::init([](const std::string& spec) { return strata::Device::open(spec); }),
           py::arg("spec") = "")
      .def_property_readonly("label", &strata::Device::label);

  py::class_<strata::Geometry>(m, "Geometry", "A validated triangle scene.")
      .def_property_readonly("triangle_count", &strata::Geometry::triangleCount)
      .def_property_readonly("vertex_count", &strata::Geometry::vertexCount)
      .def_property_readonly("source", &strata::Geometry::source)
      .def_property_readonly("bounding_sphere", [](const strata::Geometry& g) {
        float c[3], r = 0.0f;
        g.boundingSphere(c, &r);
        return py::make_tuple(py::make_tuple(c[0], c[1], c[2]), r);
      });
  m.def("load", &strata::Geometry::load, py::arg("path"), py::arg("alpha") = -1.0f,
        "A mesh file (OBJ, PLY, OFF, STL, glTF, GLB) or builtin:NAME; alpha >= 0 replaces every "
        "opacity.");
  m.def(
      "from_arrays", &fromArrays, py::arg("positions"), py::arg("indices"),
      py::arg("colors") = py::none(), py::arg("alpha") = -1.0f,
      "One mesh from an (N, 3) float array of positions, an (M, 3) integer array of vertex indices "
      "and optional (M, 4) RGBA per triangle (alpha = opacity).");

  py::class_<PyRenderer>(m, "Renderer",
                         "A renderer of one method: set_geometry once, render many views.")
      .def(py::init([](const strata::Device& device, const std::string& method,
                       const std::string& effect, int k, float sigma, int frames,
                       const std::string& batch, const std::string& sort, const std::string& atlas,
                       const std::string& decompose, const std::string& cache_dir,
                       bool depth_complexity, const std::string& octree_variant, uint32_t leaf_tris,
                       uint32_t octree_k, double memory_budget_mb, float orbit,
                       const std::string& tile_kernels) {
             strata::RenderOptions o;
             o.effect = parseEffect(effect);
             o.k = k;
             o.sigma = sigma;
             o.frames = frames;
             o.orbit_deg = orbit;
             o.tile_kernels = tile_kernels;
             o.batch = batch;
             o.sort = sort;
             o.atlas = atlas;
             o.decompose = decompose;
             o.cell_cache_dir = cache_dir;
             o.capture_depth_complexity = depth_complexity;
             o.octree.variant = octree_variant;
             o.octree.leaf_triangles = leaf_tris;
             o.octree.k = octree_k;
             if (!(memory_budget_mb >= 0.0))
               throw strata::Error("memory_budget_mb must be a number of megabytes >= 0");
             o.memory_budget = uint64_t(memory_budget_mb * 1024.0 * 1024.0);
             return new PyRenderer{strata::Renderer(device, method, o)};
           }),
           py::arg("device"), py::arg("method"), py::arg("effect") = "transparency",
           py::arg("k") = 16, py::arg("sigma") = -1.0f, py::arg("frames") = 1,
           py::arg("batch") = "static", py::arg("sort") = "none", py::arg("atlas") = "packed",
           py::arg("decompose") = "strict", py::arg("cache_dir") = "",
           py::arg("depth_complexity") = false, py::arg("octree_variant") = "kbuffer",
           py::arg("leaf_tris") = strata::OctreeMethodOptions{}.leaf_triangles,
           py::arg("octree_k") = strata::OctreeMethodOptions{}.k, py::arg("memory_budget_mb") = 0.0,
           py::arg("orbit") = 0.0f, py::arg("tile_kernels") = "auto")
      .def("set_geometry",
           [](PyRenderer& r, const strata::Geometry& g) { r.renderer.setGeometry(g); })
      .def("render", &PyRenderer::render, py::arg("az") = 30.0f, py::arg("el") = 20.0f,
           py::arg("width") = 512, py::arg("height") = 512, py::arg("distance") = 0.0f,
           py::arg("ortho") = false, py::arg("fov") = 40.0f,
           "Renders one view; returns an (height, width, 4) uint8 RGBA array. Statistics: .stats")
      .def_readonly("stats", &PyRenderer::stats,
                    "The last frame's statistics (as strata render --stats)")
      .def_readonly("depth_complexity", &PyRenderer::depth_complexity,
                    "Fragments per pixel of the last frame (with depth_complexity=True)")
      .def_property_readonly("method",
                             [](const PyRenderer& r) { return methodDict(r.renderer.method()); });

  py::class_<strata::Picker>(m, "Picker", "ID picking: the front-most object under pixels.")
      .def(py::init<const strata::Device&>(), py::arg("device"))
      .def("set_geometry", &strata::Picker::setGeometry)
      .def(
          "pick",
          [](strata::Picker& p, const std::vector<std::pair<int, int>>& pixels, float az, float el,
             int width, int height, float distance, bool ortho, float fov) {
            const strata::View view = makeView(az, el, width, height, distance, ortho, fov);
            std::vector<strata::PickHit> hits;
            {
              py::gil_scoped_release release;
              hits = p.pick(view, pixels);
            }
            py::list out;
            for (const strata::PickHit& h : hits) {
              py::dict d;
              d["hit"] = h.hit;
              if (h.hit) {
                d["object"] = h.object;
                d["triangle"] = h.triangle;
                d["name"] = h.name;
                d["depth"] = h.depth;
                d["position"] = py::make_tuple(h.position[0], h.position[1], h.position[2]);
                d["normal"] = py::make_tuple(h.normal[0], h.normal[1], h.normal[2]);
                d["front_facing"] = h.front_facing;
              }
              out.append(d);
            }
            return out;
          },
          py::arg("pixels"), py::arg("az") = 30.0f, py::arg("el") = 20.0f, py::arg("width") = 512,
          py::arg("height") = 512, py::arg("distance") = 0.0f, py::arg("ortho") = false,
          py::arg("fov") = 40.0f);
}
