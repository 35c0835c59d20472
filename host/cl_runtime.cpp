#include "host/cl_runtime.h"

#include <sys/mman.h>
#include <unistd.h>
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <mutex>
#include <optional>
#include <sstream>

#include "kernels/strata_shared.h"
#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "preprocess/core/hash.h"

namespace strata {

const std::vector<std::pair<const char*, const char*>>& embeddedKernelSources();

namespace fs = std::filesystem;

// The shared header and helpers, concatenated first in this order (docs/architecture.md); every
// other kernel file of the build follows in name order, one stage each.
static const char* const kSharedFiles[] = {"strata_shared.h",     "common.cl",    "texture.cl",
                                           "geometry.cl",         "tile_walk.cl", "local_layers.cl",
                                           "ordered_composite.cl"};

static std::vector<std::string> programFiles() {
  std::vector<std::string> files(std::begin(kSharedFiles), std::end(kSharedFiles));
  std::vector<std::string> stages;
  for (const auto& [name, text] : embeddedKernelSources()) {
    const std::string file = name;
    if (file.size() > 3 && file.compare(file.size() - 3, 3, ".cl") == 0 &&
        std::find(files.begin(), files.end(), file) == files.end())
      stages.push_back(file);
  }
  std::sort(stages.begin(), stages.end());
  files.insert(files.end(), stages.begin(), stages.end());
  return files;
}

const std::vector<std::string>& requiredExtensions() {
  // 64-bit atomics: a work-group merges (depth, id) words with atom_min, and the frame counters
  // are 64-bit.
  static const std::vector<std::string> ext = {"cl_khr_int64_base_atomics",
                                               "cl_khr_int64_extended_atomics"};
  return ext;
}

bool DeviceInfo::hasExtension(const std::string& e) const {
  return std::find(extensions.begin(), extensions.end(), e) != extensions.end();
}

bool DeviceInfo::hasInt64Atomics() const {
  for (const std::string& e : requiredExtensions())
    if (!hasExtension(e)) return false;
  return true;
}

void checkAtomicsChoice(const std::string& choice) {
  if (choice != "auto" && choice != "64" && choice != "32")
    throw Error("unknown atomics choice '" + choice + "' (auto, 64 or 32)");
}

bool useInt64Atomics(const DeviceInfo& device, const std::string& choice) {
  checkAtomicsChoice(choice);
  if (choice == "64" || (choice == "auto" && device.hasInt64Atomics())) {
    checkRequiredExtensions(device);
    return true;
  }
  // Without 64-bit atomics a counter is two 32-bit words, the low one first.
  if (!device.little_endian)
    throw DeviceError("OpenCL device " + device.name +
                      (device.hasInt64Atomics()
                           ? " is big-endian: strata's path without 64-bit "
                             "atomics needs a little-endian device"
                           : " lacks the extension " + requiredExtensions().front() +
                                 " and is big-endian: strata cannot run "
                                 "there (pick another with --device)"));
  return false;
}

bool DeviceInfo::isPocl() const {
  return platform.find("Portable Computing Language") != std::string::npos;
}

bool DeviceInfo::isOclgrind() const { return platform == "Oclgrind"; }

bool DeviceInfo::isLlvmpipe() const { return name.rfind("llvmpipe", 0) == 0; }

std::string DeviceInfo::label() const {
  return name + " (" + platform + ", " + driver_version + ")";
}

const char* clErrorName(cl_int code) {
  switch (code) {
#define CASE(x) \
  case x:       \
    return #x;
    // clang-format off
    CASE(CL_SUCCESS)
    CASE(CL_DEVICE_NOT_FOUND)
    CASE(CL_DEVICE_NOT_AVAILABLE)
    CASE(CL_COMPILER_NOT_AVAILABLE)
    CASE(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    CASE(CL_OUT_OF_RESOURCES)
    CASE(CL_OUT_OF_HOST_MEMORY)
    CASE(CL_PROFILING_INFO_NOT_AVAILABLE)
    CASE(CL_BUILD_PROGRAM_FAILURE)
    CASE(CL_INVALID_VALUE)
    CASE(CL_INVALID_DEVICE_TYPE)
    CASE(CL_INVALID_PLATFORM)
    CASE(CL_INVALID_DEVICE)
    CASE(CL_INVALID_CONTEXT)
    CASE(CL_INVALID_QUEUE_PROPERTIES)
    CASE(CL_INVALID_COMMAND_QUEUE)
    CASE(CL_INVALID_HOST_PTR)
    CASE(CL_INVALID_MEM_OBJECT)
    CASE(CL_INVALID_BINARY)
    CASE(CL_INVALID_BUILD_OPTIONS)
    CASE(CL_INVALID_PROGRAM)
    CASE(CL_INVALID_PROGRAM_EXECUTABLE)
    CASE(CL_INVALID_KERNEL_NAME)
    CASE(CL_INVALID_KERNEL)
    CASE(CL_INVALID_ARG_INDEX)
    CASE(CL_INVALID_ARG_VALUE)
    CASE(CL_INVALID_ARG_SIZE)
    CASE(CL_INVALID_KERNEL_ARGS)
    CASE(CL_INVALID_WORK_DIMENSION)
    CASE(CL_INVALID_WORK_GROUP_SIZE)
    CASE(CL_INVALID_WORK_ITEM_SIZE)
    CASE(CL_INVALID_GLOBAL_OFFSET)
    CASE(CL_INVALID_EVENT_WAIT_LIST)
    CASE(CL_INVALID_EVENT)
    CASE(CL_INVALID_OPERATION)
    CASE(CL_INVALID_BUFFER_SIZE)
    CASE(CL_INVALID_GLOBAL_WORK_SIZE)
    CASE(CL_PLATFORM_NOT_FOUND_KHR)
    CASE(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
    // clang-format on
#undef CASE
    default:
      return "unknown OpenCL error";
  }
}

void rethrowClError(const cl::Error& e, const std::string& context) {
  std::string msg = "OpenCL call " + std::string(e.what()) + " failed with " +
                    clErrorName(e.err()) + " (" + std::to_string(e.err()) + ")";
  if (!context.empty()) msg += " while " + context;
  if (e.err() == CL_MEM_OBJECT_ALLOCATION_FAILURE || e.err() == CL_OUT_OF_HOST_MEMORY)
    throw OutOfMemory("out of memory: " + msg);
  throw DeviceError(msg);
}

static std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\0' || std::isspace((unsigned char)s.back()))) s.pop_back();
  return s;
}

// Every (platform, device) pair in enumeration order: the order device indices refer to. The
// platforms without a device go to `empty`, if given.
static std::vector<std::pair<cl::Platform, cl::Device>> enumerateDevices(
    std::vector<std::string>* empty = nullptr) {
  std::vector<std::pair<cl::Platform, cl::Device>> out;
  std::vector<cl::Platform> platforms;
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error& e) {
    // The ICD loader reports "no platform" as an error.
    if (e.err() == CL_PLATFORM_NOT_FOUND_KHR) return out;
    rethrowClError(e, "listing OpenCL platforms");
  }
  for (cl::Platform& p : platforms) {
    std::vector<cl::Device> devices;
    try {
      p.getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error&) {
      devices.clear();  // a platform with no devices
    }
    if (devices.empty() && empty) {
      try {
        empty->push_back(trimmed(p.getInfo<CL_PLATFORM_NAME>()));
      } catch (const cl::Error&) {
        empty->push_back("(unnamed)");
      }
    }
    for (cl::Device& d : devices) out.emplace_back(p, d);
  }
  return out;
}

std::vector<DeviceInfo> listDevices() {
  std::vector<DeviceInfo> out;
  int index = 0;
  for (auto& [p, d] : enumerateDevices()) {
    DeviceInfo info;
    info.index = index++;
    info.platform = p.getInfo<CL_PLATFORM_NAME>();
    info.name = d.getInfo<CL_DEVICE_NAME>();
    info.vendor = d.getInfo<CL_DEVICE_VENDOR>();
    info.version = d.getInfo<CL_DEVICE_VERSION>();
    info.driver_version = d.getInfo<CL_DRIVER_VERSION>();
    info.is_gpu = (d.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU) != 0;
    info.little_endian = d.getInfo<CL_DEVICE_ENDIAN_LITTLE>() != CL_FALSE;
    info.global_mem_bytes = d.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
    info.max_alloc_bytes = d.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
    info.max_work_group_size = d.getInfo<CL_DEVICE_MAX_WORK_GROUP_SIZE>();
    std::istringstream ext(d.getInfo<CL_DEVICE_EXTENSIONS>());
    for (std::string e; ext >> e;) info.extensions.push_back(e);
    for (auto& s : {&info.platform, &info.name, &info.version, &info.driver_version})
      *s = trimmed(*s);
    out.push_back(info);
  }
  return out;
}

static std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower((unsigned char)c));
  return s;
}

std::vector<EmptyPlatform> platformsWithoutDevices() {
  std::vector<std::string> names;
  enumerateDevices(&names);
  std::vector<EmptyPlatform> out;
  for (const std::string& n : names) {
    EmptyPlatform e{n, ""};
    // Mesa's rusticl lists its devices only when told which drivers to use.
    if (lower(n) == "rusticl")
      e.hint = "set RUSTICL_ENABLE=llvmpipe for its CPU device (or the name of a GPU driver)";
    out.push_back(e);
  }
  return out;
}

// Whether a folder exists (or can be made: it is made, as the driver would have) and may be
// written.
static bool folderUsable(const fs::path& p) {
  std::error_code ec;
  if (!fs::exists(p, ec)) fs::create_directories(p, ec);
  return fs::is_directory(p, ec) && ::access(p.c_str(), W_OK | X_OK) == 0;
}

// PoCL keeps compiled kernels in POCL_CACHE_DIR, else $XDG_CACHE_HOME/pocl, else ~/.cache/pocl
// (the kernel libraries under kcache/ there).
static fs::path poclCacheFolder() {
  if (const char* p = std::getenv("POCL_CACHE_DIR"); p && *p) return p;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return fs::path(x) / "pocl";
  if (const char* h = std::getenv("HOME"); h && *h) return fs::path(h) / ".cache" / "pocl";
  return {};
}

// Whether a kernel library in PoCL's cache is whole: an ELF file at least as long as its program
// and section header tables say. PoCL dlopens these files and aborts the process when that
// fails, so one cut short (a full disk, a crash while writing) would end every later run.
static bool elfLooksWhole(const fs::path& path, uintmax_t size) {
  unsigned char h[64] = {};
  std::ifstream in(path, std::ios::binary);
  if (!in.read(reinterpret_cast<char*>(h), sizeof(h))) return false;
  if (std::memcmp(h,
                  "\x7f"
                  "ELF",
                  4) != 0 ||
      h[5] != 1)
    return false;  // little-endian ELF
  auto u16 = [&](int at) { return uint64_t(h[at]) | uint64_t(h[at + 1]) << 8; };
  auto u32 = [&](int at) { return u16(at) | u16(at + 2) << 16; };
  auto u64 = [&](int at) { return u32(at) | u32(at + 4) << 32; };
  uint64_t phoff, shoff, phsize, shsize;
  if (h[4] == 2) {  // 64-bit
    phoff = u64(32), shoff = u64(40), phsize = u16(54) * u16(56), shsize = u16(58) * u16(60);
  } else if (h[4] == 1) {
    phoff = u32(28), shoff = u32(32), phsize = u16(42) * u16(44), shsize = u16(46) * u16(48);
  } else {
    return false;
  }
  return phoff <= size && phsize <= size - phoff && shoff <= size && shsize <= size - shoff;
}

// Free space below which a failed PoCL build is put down to a full cache folder: compiling
// strata's program writes a few megabytes of temporary files there.
constexpr uintmax_t kPoclBuildSpaceBytes = uintmax_t(8) << 20;

// Whether `name` is one of PoCL's temporary names ("tempfile_" and six characters of mkstemp).
static bool poclTemporaryName(const std::string& name) {
  return name.size() == 15 && name.rfind("tempfile_", 0) == 0;
}

// Removes the kernel libraries of PoCL's cache that are not whole (PoCL compiles them again),
// and the empty temporary files PoCL leaves there: each process that initialises PoCL creates one
// (its test that the folder is writable) and never removes it, so a cache used by thousands of
// runs held thousands. Only empty ones a minute old or more go: a writer that has written nothing
// for a minute is gone (PoCL also writes kernels through such names, then renames them). Once per
// process; a cache of other programs' kernels is only read (ELF headers), at most 200,000 files.
static void removeDamagedPoclKernels() {
  static std::once_flag once;
  std::call_once(once, [] {
    const fs::path folder = poclCacheFolder();
    if (folder.empty()) return;
    std::error_code ec;
    const fs::path root = std::getenv("POCL_CACHE_DIR") ? folder : folder / "kcache";
    if (!fs::is_directory(root, ec)) return;
    size_t seen = 0, removed = 0;
    fs::recursive_directory_iterator it(root, fs::directory_options::skip_permission_denied, ec);
    const auto minute_ago = fs::file_time_type::clock::now() - std::chrono::minutes(1);
    for (; !ec && it != fs::recursive_directory_iterator() && seen < 200000; it.increment(ec)) {
      const fs::directory_entry& e = *it;
      if (it.depth() == 0 && poclTemporaryName(e.path().filename().string()) &&
          e.is_regular_file(ec) && e.file_size(ec) == 0 && !ec &&
          e.last_write_time(ec) < minute_ago && !ec) {
        std::error_code ignored;
        fs::remove(e.path(), ignored);
        continue;
      }
      ec.clear();
      if (e.path().extension() != ".so" || !e.is_regular_file(ec)) continue;
      // PoCL links a kernel library into a temporary "tempfile_XXXXXX.so" and renames it when
      // whole: one not whole yet is another process's link in progress (removing it made that
      // process abort with "Final linking of kernel ... failed").
      if (e.path().filename().string().rfind("tempfile_", 0) == 0) continue;
      ++seen;
      const uintmax_t size = e.file_size(ec);
      if (ec || elfLooksWhole(e.path(), size)) continue;
      if (fs::remove(e.path(), ec)) ++removed;
    }
    if (removed > 0)
      std::cerr << "strata: warning: removed " << removed
                << " damaged kernel libraries from the OpenCL driver's cache " << root.string()
                << "\n";
  });
}

std::string noDeviceMessage() {
  // PoCL offers no device at all when it cannot make its cache folder.
  const fs::path cache = poclCacheFolder();
  if (!cache.empty() && !folderUsable(cache))
    return "no OpenCL device found: the OpenCL driver's cache folder " + cache.string() +
           " cannot be made or written (set XDG_CACHE_HOME or POCL_CACHE_DIR to a writable "
           "folder)";
  return "no OpenCL device found: install an OpenCL driver (e.g. apt-get install "
         "pocl-opencl-icd)";
}

DeviceInfo chooseDevice(const std::string& spec_in) {
  std::string spec = spec_in;
  std::vector<DeviceInfo> devices = listDevices();
  if (devices.empty()) throw DeviceError(noDeviceMessage());
  if (spec.empty()) {
    for (const DeviceInfo& d : devices)
      if (d.is_gpu) return d;
    return devices.front();
  }
  const bool numeric =
      std::all_of(spec.begin(), spec.end(), [](char c) { return std::isdigit((unsigned char)c); });
  if (numeric) {
    // Compared as digits, so an index past any integer type is simply one that does not exist.
    const std::string digits = spec.substr(std::min(spec.find_first_not_of('0'), spec.size() - 1));
    const size_t i = digits.size() <= 9 ? size_t(std::stoul(digits)) : devices.size();
    if (i < devices.size()) return devices[i];
    throw Error("device index " + spec + " does not exist: " + std::to_string(devices.size()) +
                " OpenCL device(s) found (see `strata info`)");
  }
  for (const DeviceInfo& d : devices)
    if (lower(d.name).find(lower(spec)) != std::string::npos ||
        lower(d.platform).find(lower(spec)) != std::string::npos)
      return d;
  // A platform that matches but shows no device: say so, and how to give it one.
  for (const EmptyPlatform& p : platformsWithoutDevices())
    if (lower(p.name).find(lower(spec)) != std::string::npos)
      throw Error("OpenCL platform " + p.name + " (matching '" + spec + "') has no device" +
                  (p.hint.empty() ? std::string() : ": " + p.hint) + " (see `strata info`)");
  throw Error("no OpenCL device matches '" + spec + "' (see `strata info`)");
}

// Program cache files: the binary framed by frameCachePayload under "STRATAPB".
constexpr char kProgramCacheMagic[8] = {'S', 'T', 'R', 'A', 'T', 'A', 'P', 'B'};
constexpr size_t kMaxProgramCacheBytes = size_t(1) << 30;

static std::optional<std::vector<unsigned char>> readProgramCache(const fs::path& file) {
  const std::optional<std::string> bytes = readCacheFile(file, kMaxProgramCacheBytes);
  if (!bytes) return std::nullopt;
  const std::optional<std::string_view> binary = unframeCachePayload(kProgramCacheMagic, *bytes);
  if (!binary) return std::nullopt;
  return std::vector<unsigned char>(binary->begin(), binary->end());
}

static void writeProgramCache(const fs::path& file, const std::vector<unsigned char>& binary) {
  std::error_code ec;
  fs::create_directories(file.parent_path(), ec);
  const std::string_view payload(reinterpret_cast<const char*>(binary.data()), binary.size());
  writeCacheFileAtomically(file, "program cache", frameCachePayload(kProgramCacheMagic, payload));
}

// Kernel sources: embedded at build time, or read from STRATA_KERNEL_DIR for kernel work.
static std::vector<std::pair<std::string, std::string>> programSources() {
  std::vector<std::pair<std::string, std::string>> out;
  const char* dir = std::getenv("STRATA_KERNEL_DIR");
  for (const std::string& file : programFiles()) {
    if (dir && *dir) {
      std::ifstream in(std::string(dir) + "/" + file, std::ios::binary);
      if (!in)
        throw Error(std::string(dir) + "/" + file +
                    ": cannot read kernel source (STRATA_KERNEL_DIR)");
      std::stringstream ss;
      ss << in.rdbuf();
      out.emplace_back(file, ss.str());
      continue;
    }
    bool found = false;
    for (const auto& [name, text] : embeddedKernelSources()) {
      if (file == name) {
        out.emplace_back(file, text);
        found = true;
      }
    }
    if (!found) throw Error("kernel source " + file + " is not embedded in this build");
  }
  return out;
}

std::shared_ptr<ClRuntime> ClRuntime::acquire(const std::string& spec, const std::string& atomics) {
  // Only weak references are kept here: the registry never owns a runtime, so none outlives
  // its last renderer (a static owner would release OpenCL objects after main returns).
  static std::mutex mutex;
  static std::map<std::pair<int, bool>, std::weak_ptr<ClRuntime>> runtimes;
  checkAtomicsChoice(atomics);
  std::lock_guard<std::mutex> lock(mutex);
  const DeviceInfo info = chooseDevice(spec);
  const bool int64 = useInt64Atomics(info, atomics);
  std::weak_ptr<ClRuntime>& slot = runtimes[{info.index, int64}];
  if (std::shared_ptr<ClRuntime> alive = slot.lock()) return alive;
  std::shared_ptr<ClRuntime> made(new ClRuntime(info, int64));
  slot = made;
  return made;
}

ClRuntime::~ClRuntime() {
  // Destructors only log: pending work is finished before the objects go.
  try {
    if (queue_()) queue_.finish();
  } catch (const cl::Error& e) {
    std::cerr << "strata: warning: finishing the queue of " << info_.name << ": "
              << clErrorName(e.err()) << "\n";
  }
}

void checkRequiredExtensions(const DeviceInfo& device) {
  for (const std::string& e : requiredExtensions())
    if (!device.hasExtension(e))
      throw DeviceError("OpenCL device " + device.name + " lacks the extension " + e +
                        " that strata's 64-bit atomics path needs (use --atomics auto or 32, or "
                        "pick another device with --device)");
}

ClRuntime::ClRuntime(const DeviceInfo& info, bool int64_atomics)
    : info_(info), int64_atomics_(int64_atomics) {
  static std::once_flag llvmpipe_warned;  // once per process, however many runtimes
  if (info_.isLlvmpipe())
    std::call_once(llvmpipe_warned, [this] {
      std::cerr << "strata: warning: " << info_.name
                << " ends a kernel's loops after 65,535 iterations per work-item: frames of "
                   "many triangles or long tile lists lose fragments there, and cells and "
                   "octree lose whole blocks above 32x32 pixels (docs/results/devices.md)\n";
    });
  try {
    const auto devices = enumerateDevices();
    if (info_.index < 0 || size_t(info_.index) >= devices.size())
      throw DeviceError("OpenCL device " + std::to_string(info_.index) + " disappeared");
    platform_ = devices[size_t(info_.index)].first;
    device_ = devices[size_t(info_.index)].second;
    context_ = cl::Context(device_);
    queue_ = cl::CommandQueue(context_, device_, CL_QUEUE_PROFILING_ENABLE);
  } catch (const cl::Error& e) {
    rethrowClError(e, "creating a context on " + info_.name);
  }
  buildProgram();
}

void ClRuntime::buildProgram() {
  // PoCL's prefetch() is empty; its Clang compiler takes __builtin_prefetch, which the tile walk
  // uses when ST_USE_BUILTIN_PREFETCH is set (other compilers, Oclgrind's included, may not
  // accept it). ST_ROW_LANES: the tile walk tests a tile row as the eight lanes of a vector,
  // which PoCL turns into SIMD; a GPU runs the plain loop over a row's pixels (fewer steps for
  // small triangles), and so does Oclgrind, whose uninitialised-value checker crashes on it.
  // ST_WORK_ITEMS_IN_TURN: PoCL runs a work-group's items one after another, which some kernels
  // (the bin scan) are written for. ST_USE_BUILTIN_RINT: PoCL's rint() is a software routine
  // (common.cl).
  const bool pocl = info_.isPocl();
  if (pocl) removeDamagedPoclKernels();
  // ST_NO_INT64_ATOMICS: the path without 64-bit atomics (common.cl).
  const std::string options =
      std::string("-cl-std=CL1.2") +
      (pocl ? " -DST_USE_BUILTIN_PREFETCH -DST_USE_BUILTIN_RINT -DST_ROW_LANES"
              " -DST_WORK_ITEMS_IN_TURN"
            : "") +
      (int64_atomics_ ? "" : " -DST_NO_INT64_ATOMICS");
  std::vector<std::pair<std::string, std::string>> sources = programSources();
  std::string key_text = info_.platform + "\n" + info_.name + "\n" + info_.version + "\n" +
                         info_.driver_version + "\n" + options + "\n";
  for (const auto& [name, text] : sources) key_text += name + "\n" + text;
  // Oclgrind compiles with the options of its own command line too (--build-options, passed in
  // this variable), which change the binary: one built without them is not reused with them.
  if (const char* extra = std::getenv("OCLGRIND_BUILD_OPTIONS"))
    key_text += std::string("OCLGRIND_BUILD_OPTIONS=") + extra + "\n";
  char key[32];
  std::snprintf(key, sizeof(key), "%016llx", (unsigned long long)fnv1a64(key_text));
  const fs::path cache_file = userCacheDir("programs") / (std::string(key) + ".bin");
  removeStaleTemporaries(cache_file.parent_path());

  // A cached binary is keyed on everything that affects it and framed with its length and
  // checksum, so a truncated or damaged file is rebuilt instead of handed to the driver; one that
  // still fails to load or build is replaced.
  if (std::optional<std::vector<unsigned char>> bin = readProgramCache(cache_file)) {
    try {
      cl::Program::Binaries binaries{*bin};
      program_ = cl::Program(context_, {device_}, binaries);
      program_.build({device_}, options.c_str());
      return;
    } catch (const cl::Error&) {
      removeQuietly(cache_file);
    }
  }

  cl::Program::Sources cl_sources;
  // Each file starts on a fresh line and #line keeps compiler messages pointing at the file.
  std::vector<std::string> texts;
  for (const auto& [name, text] : sources)
    texts.push_back("#line 1 \"" + name + "\"\n" + text + "\n");
  for (const std::string& t : texts) cl_sources.push_back(t);
  // Compiling takes tens of seconds on a CPU driver, once per device, driver and source: on a
  // terminal, say why the first run waits (redirected output stays clean).
  const bool tell = isatty(STDERR_FILENO) != 0;
  const auto compile_start = std::chrono::steady_clock::now();
  if (tell) {
    std::fprintf(stderr,
                 "strata: compiling the OpenCL kernels for %s, once per device and driver "
                 "(kept in %s) ...",
                 info_.name.c_str(), cache_file.parent_path().c_str());
    std::fflush(stderr);
  }
  try {
    program_ = cl::Program(context_, cl_sources);
    program_.build({device_}, options.c_str());
    if (tell)
      std::fprintf(
          stderr, " %.1f s\n",
          std::chrono::duration<double>(std::chrono::steady_clock::now() - compile_start).count());
  } catch (const cl::Error& e) {
    if (tell) std::fprintf(stderr, " failed\n");
    if (e.err() == CL_BUILD_PROGRAM_FAILURE || e.err() == CL_INVALID_PROGRAM_EXECUTABLE) {
      // PoCL compiles through files in its cache folder: on a full disk the build fails with a
      // log that does not say why. Such a folder is named instead of the log.
      if (const fs::path folder = poclCacheFolder(); pocl && !folder.empty()) {
        std::error_code ec;
        const fs::space_info space = fs::space(folder, ec);
        if (!ec && space.available < kPoclBuildSpaceBytes)
          throw DeviceError("building the OpenCL kernels failed on " + info_.name +
                            ": the OpenCL driver's cache folder " + folder.string() + " has only " +
                            std::to_string(space.available / 1024) +
                            " KiB free (PoCL compiles through it): free space there, or set "
                            "POCL_CACHE_DIR to a folder with room");
      }
      std::string log;
      try {
        log = program_.getBuildInfo<CL_PROGRAM_BUILD_LOG>(device_);
      } catch (const cl::Error&) {
      }
      std::cerr << "strata: OpenCL build log for " << info_.name << ":\n" << log << "\n";
      throw DeviceError("building the OpenCL kernels failed on " + info_.name +
                        " (build log printed above)");
    }
    rethrowClError(e, "building the OpenCL kernels");
  }
  // Store the binary for the next process. The cache is an optimisation: a device that cannot
  // return binaries, or a folder that cannot be written, just means the next run builds again.
  try {
    std::vector<std::vector<unsigned char>> bins = program_.getInfo<CL_PROGRAM_BINARIES>();
    if (!bins.empty() && !bins[0].empty()) writeProgramCache(cache_file, bins[0]);
  } catch (const cl::Error&) {
  } catch (const Error& e) {
    std::cerr << "strata: warning: " << printableMessage(e.what())
              << " (the kernels are not cached: the next run compiles them again)\n";
  }
}

void ClRuntime::fill(cl::Buffer& b, uint32_t pattern, size_t bytes, const std::string& purpose,
                     cl::Event* event) {
  STRATA_CHECK(bytes % 4 == 0);
  const size_t words = bytes / 4;
  if (words == 0) return;
  const size_t global = (words + ST_LINEAR_WG - 1) / ST_LINEAR_WG * ST_LINEAR_WG;
  std::lock_guard<std::mutex> lock(fill_mutex_);
  try {
    if (!fill_kernel_()) fill_kernel_ = cl::Kernel(program_, "fill_words");
    fill_kernel_.setArg(0, b);
    fill_kernel_.setArg(1, cl_uint(pattern));
    fill_kernel_.setArg(2, cl_ulong(words));
    queue_.enqueueNDRangeKernel(fill_kernel_, cl::NullRange, cl::NDRange(global),
                                cl::NDRange(ST_LINEAR_WG), nullptr, event);
  } catch (const cl::Error& e) {
    rethrowClError(e, purpose);
  }
}

cl::Kernel ClRuntime::kernel(const std::string& name) {
  try {
    return cl::Kernel(program_, name.c_str());
  } catch (const cl::Error& e) {
    rethrowClError(e, "creating kernel " + name);
  }
}

namespace {
std::atomic<uint64_t> g_live_bytes_of_all_devices{0};
}  // namespace

uint64_t ClRuntime::liveBytesOfAllDevices() { return g_live_bytes_of_all_devices.load(); }

cl::Buffer ClRuntime::allocate(size_t bytes, const std::string& purpose, cl_mem_flags flags) {
  if (bytes > info_.max_alloc_bytes)
    throw DeviceError("device " + info_.name + " cannot allocate " + std::to_string(bytes) +
                      " bytes for " + purpose + ": its largest allocation is " +
                      std::to_string(info_.max_alloc_bytes) + " bytes");
  const size_t size = std::max<size_t>(bytes, 16);
  const uint64_t live = live_bytes_->load();
  if (info_.global_mem_bytes && live + size > info_.global_mem_bytes)
    throw OutOfMemory("device " + info_.name + " is out of memory: " + std::to_string(bytes) +
                      " bytes for " + purpose + " with " + std::to_string(live) +
                      " bytes already in use, of " + std::to_string(info_.global_mem_bytes));
  // A CPU device's buffer is host memory, and a frame's large buffers are read and written at
  // scattered places (setup records, tile lists and their tables): on 4 KiB pages most of those
  // accesses miss the TLB. Large buffers are backed by memory of our own on transparent huge
  // pages (madvise, so also where the system's default is madvise), handed to the device as its
  // storage (CL_MEM_USE_HOST_PTR: PoCL's CPU devices use such memory in place). Every other
  // buffer of such a device is backed by memory of our own too: PoCL allocates a buffer's
  // storage only when a command first uses it, and aborts there if that fails, so the memory
  // is had (or refused with an error) here instead.
  // Counted while the buffer lives: its release (perhaps after the commands using it) subtracts
  // and frees its host memory. Made first, so that failing to make it leaks nothing.
  struct Release {
    std::shared_ptr<std::atomic<uint64_t>> live;
    uint64_t bytes;
    void* host_memory;
  };
  auto release = std::make_unique<Release>(Release{live_bytes_, size, nullptr});
  void* host_memory = nullptr;
  const bool own_memory =
      !info_.is_gpu && info_.isPocl() &&
      !(flags & (CL_MEM_USE_HOST_PTR | CL_MEM_ALLOC_HOST_PTR | CL_MEM_COPY_HOST_PTR));
  if (own_memory) {
    const bool huge = size >= kHugePageBufferBytes;
    const size_t alignment = huge ? kHugePageBytes : kHostBufferAlignment;
    const size_t rounded = (size + alignment - 1) / alignment * alignment;
    host_memory = std::aligned_alloc(alignment, rounded);
    if (!host_memory)
      throw OutOfMemory("device " + info_.name + " is out of memory: " + std::to_string(bytes) +
                        " bytes for " + purpose + " (host memory exhausted, with " +
                        std::to_string(live) + " bytes already in use)");
    if (huge) madvise(host_memory, rounded, MADV_HUGEPAGE);  // a hint: failure is harmless
  }
  cl::Buffer buffer;
  if (host_memory) {
    try {
      buffer = cl::Buffer(context_, flags | CL_MEM_USE_HOST_PTR, size, host_memory);
    } catch (const cl::Error&) {  // then the device's own memory, as for any other buffer
      std::free(host_memory);
      host_memory = nullptr;
    }
  }
  if (!host_memory) {
    try {
      buffer = cl::Buffer(context_, flags, size);
    } catch (const cl::Error& e) {  // an OutOfMemory for the allocation failures
      rethrowClError(e, "allocating " + std::to_string(bytes) + " bytes for " + purpose);
    }
  }
  release->host_memory = host_memory;
  *live_bytes_ += size;
  g_live_bytes_of_all_devices += size;
  const cl_int err = clSetMemObjectDestructorCallback(
      buffer(),
      [](cl_mem, void* data) {
        auto* r = static_cast<Release*>(data);
        *r->live -= r->bytes;
        g_live_bytes_of_all_devices -= r->bytes;
        std::free(r->host_memory);
        delete r;
      },
      release.get());
  if (err == CL_SUCCESS) {
    release.release();  // the callback owns it now
  } else {              // not counted then, and its host memory (if any) never freed
    *live_bytes_ -= size;
    g_live_bytes_of_all_devices -= size;
    release->host_memory = nullptr;
  }
  return buffer;
}

void LaunchTimer::launch(const std::string& name, cl::Kernel& k, const cl::NDRange& global,
                         const cl::NDRange& local, const cl::NDRange& offset) {
  cl::Event ev;
  try {
    runtime_.queue().enqueueNDRangeKernel(k, offset, global, local, nullptr, &ev);
  } catch (const cl::Error& e) {
    rethrowClError(e, "launching kernel " + name);
  }
  events_.push_back({name, k(), ev});
}

void LaunchTimer::fill(const std::string& name, cl::Buffer& b, uint32_t pattern, size_t bytes) {
  cl::Event ev;
  runtime_.fill(b, pattern, bytes, "clearing buffer for " + name, &ev);
  events_.push_back({name, nullptr, ev});
}

double LaunchTimer::eventMs(const cl::Event& ev) {
  try {
    const cl_ulong t0 = ev.getProfilingInfo<CL_PROFILING_COMMAND_START>();
    const cl_ulong t1 = ev.getProfilingInfo<CL_PROFILING_COMMAND_END>();
    return double(t1 - t0) * 1e-6;
  } catch (const cl::Error&) {
    return 0.0;  // a device without profiling: the stage is listed, time unknown
  }
}

std::map<std::string, double> LaunchTimer::stageTimes() const {
  std::map<std::string, double> out;
  for (const Launch& l : events_) out[l.stage] += eventMs(l.event);
  return out;
}

std::map<std::string, LaunchTimer::KernelTime> LaunchTimer::kernelTimes() const {
  std::map<cl_kernel, std::string> names;
  std::map<std::string, KernelTime> out;
  for (const Launch& l : events_) {
    std::string kernel = "fill";
    if (l.kernel) {
      auto [it, fresh] = names.try_emplace(l.kernel);
      if (fresh) {
        size_t size = 0;
        std::string text(256, '\0');
        if (clGetKernelInfo(l.kernel, CL_KERNEL_FUNCTION_NAME, text.size(), text.data(), &size) ==
            CL_SUCCESS)
          it->second = text.substr(0, size ? size - 1 : 0);
        else
          it->second = "kernel";
      }
      kernel = it->second;
    }
    KernelTime& t = out[l.stage + "/" + kernel];
    t.ms += eventMs(l.event);
    ++t.launches;
  }
  return out;
}

}  // namespace strata
