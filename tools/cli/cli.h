// The `strata` program's commands, one file each under tools/cli/: each adds its subcommand to
// the command line (its options and help) and says what to run once the line is parsed.
// options.cpp holds what several commands share: option parsers, the camera of a scene, output
// checks and progress bars. tools/strata_main.cpp puts them together and reports errors.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "engine/renderer.h"
#include "preprocess/mesh_view.h"

namespace strata::cli {

struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;              // once the line is parsed, if this command was chosen
  std::function<std::string()> subject;  // what it reads (an out-of-memory message names it)
  // False where this process must not print an error (the ranks after the first of an MPI job,
  // which all meet the same bad option).
  std::function<bool()> reports_errors = [] { return true; };
};

Command addInfoCommand(CLI::App& app);
Command addRenderCommand(CLI::App& app);
Command addPrepCommand(CLI::App& app);
Command addExportCommand(CLI::App& app);
Command addDiffCommand(CLI::App& app);
Command addBenchCommand(CLI::App& app);
Command addPickCommand(CLI::App& app);

// ---- shared options (options.cpp) ----------------------------------------------------------

// The device option: --device, else STRATA_DEVICE (the library itself reads no environment).
std::string deviceSpec(const std::string& option);
// Adds --device and --atomics to a command.
void addDeviceOptions(CLI::App* command, std::string& device, std::string& atomics);
// The device options: --device (deviceSpec) and --atomics, else STRATA_ATOMICS, else auto.
DeviceOptions deviceOptions(const std::string& device, const std::string& atomics);
// Comma-separated finite numbers; Error naming the option otherwise.
std::vector<float> parseFloatList(const std::string& text, const std::string& option);
// Comma-separated whole numbers; exactly `count` of them (0: any number, at least one).
std::vector<int> parseIntList(const std::string& text, size_t count, const std::string& option,
                              const std::string& form);
// --size WIDTHxHEIGHT.
void parseSize(const std::string& text, int& w, int& h);
// --background checker, #rrggbb or r,g,b.
Background parseBackground(const std::string& text);
// Fails early, before a long render, if an output file could not be written.
void checkWritable(const std::string& path, const std::string& what);
// NAME.EXT -> NAME-SUFFIX.EXT.
std::string withSuffix(const std::string& path, const std::string& suffix);
// The camera of `render` and `pick`: the scene's own view, or --view AZ,EL[,DIST], framed
// afresh; --ortho / --perspective override the scene's projection.
Camera sceneCamera(const Scene& scene, const std::string& view_text, bool ortho, bool perspective,
                   float fov);
// A progress bar on the terminal only (empty otherwise): redirected output stays clean.
std::function<void(double)> progressBar(const std::string& what);
// Every instance's triangles in world space, as one mesh.
MeshView worldMesh(const WorldGeometry& g);

}  // namespace strata::cli
