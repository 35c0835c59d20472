// strata: the command-line program. Each command is a file of tools/cli/ (info, render, prep,
// export, diff, bench, pick); this file puts them on one command line and reports errors the
// same way for all: one line "strata: error: ..." and exit 1.
#include <algorithm>
#include <iostream>
#include <new>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "strata/error.h"
#include "tools/cli/cli.h"

using namespace strata;

int main(int argc, char** argv) {
  // Ctrl-C or a kill during a long render or write leaves no temporary files behind.
  strata::removeTemporaryFilesOnSignals();
  CLI::App app{
      "strata: exact order-independent transparency with OpenCL kernels (PoCL on CPUs, "
      "any OpenCL GPU), checked against an Embree reference"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("strata ") + STRATA_VERSION);
  const std::vector<cli::Command> commands = {cli::addInfoCommand(app), cli::addRenderCommand(app),
                                              cli::addPrepCommand(app), cli::addExportCommand(app),
                                              cli::addDiffCommand(app), cli::addBenchCommand(app),
                                              cli::addPickCommand(app)};

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help
    // One line, as every other error.
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    std::cerr << "strata: error: " << printableMessage(what)
              << " (strata --help lists the options)\n";
    return 1;
  }
  for (const cli::Command& command : commands) {
    if (!*command.app) continue;
    try {
      return command.run();
    } catch (const Error& e) {
      if (!command.reports_errors()) return 1;
      std::cerr << "strata: error: " << printableMessage(e.what()) << "\n";
      return 1;
    } catch (const std::bad_alloc&) {
      // What was being read or rendered, so the message names it.
      std::cerr << "strata: error: " << printableMessage(command.subject())
                << ": out of memory (the scene or the image needs more memory than there is)\n";
      return 1;
    } catch (const std::exception& e) {
      std::cerr << "strata: internal error: " << printableMessage(e.what()) << "\n";
      return 2;
    }
  }
  return 0;
}
