// strata info: the OpenCL platforms and devices, the one chosen, the extensions strata uses.
#include <memory>
#include <string>

#include "engine/report/device_report.h"
#include "tools/cli/cli.h"

namespace strata::cli {

Command addInfoCommand(CLI::App& app) {
  auto device = std::make_shared<std::string>(), atomics = std::make_shared<std::string>();
  CLI::App* info = app.add_subcommand(
      "info",
      "OpenCL platforms and devices, the chosen device, its extensions and which path each method "
      "runs there");
  addDeviceOptions(info, *device, *atomics);
  Command c;
  c.app = info;
  c.run = [device, atomics] { return printDeviceReport(deviceOptions(*device, *atomics)); };
  c.subject = [] { return std::string("strata info"); };
  return c;
}

}  // namespace strata::cli
