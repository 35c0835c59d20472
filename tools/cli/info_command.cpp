// strata info: the OpenCL platforms and devices, the one chosen, the extensions strata uses.
#include <memory>
#include <string>

#include "engine/report/device_report.h"
#include "tools/cli/cli.h"

namespace strata::cli {

Command addInfoCommand(CLI::App& app) {
  auto device = std::make_shared<std::string>();
  CLI::App* info = app.add_subcommand(
      "info", "OpenCL platforms and devices, the chosen device, extensions used");
  info->add_option(
      "--device", *device,
      "device index or name substring (default: STRATA_DEVICE, else a GPU, else the first device)");
  Command c;
  c.app = info;
  c.run = [device] { return printDeviceReport(deviceSpec(*device)); };
  c.subject = [] { return std::string("strata info"); };
  return c;
}

}  // namespace strata::cli
