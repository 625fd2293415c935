// sls devices: what the drivers of this build find connected now, one line per device with the
// URI that opens it (drivers/device_registry.h). The built-in simulator is always listed; with
// no hardware the command says so and still succeeds.
//
//   sls devices [--json]
#include <algorithm>
#include <iostream>

#include <fmt/format.h>

#include "drivers/device_registry.h"
#include "samples/sls/commands.h"

namespace sls::cli {
namespace {

nlohmann::json device_json(const drivers::DeviceDescription& device) {
  return {{"kind", drivers::device_kind_name(device.kind)},
          {"uri", device.uri},
          {"model", device.model},
          {"serial", device.serial},
          {"details", device.details},
          {"opens_as", drivers::device_role_names(device.roles)}};
}

nlohmann::json transport_json(const drivers::TransportSearch& transport) {
  return {{"name", transport.name}, {"covers", transport.covers}, {"searched", transport.searched},
          {"problem", transport.problem}};
}

void print_human(const drivers::DeviceEnumeration& found) {
  std::size_t uri_width = 0;
  for (const auto& device : found.devices) uri_width = std::max(uri_width, device.uri.size());
  for (const auto& device : found.devices) {
    std::string what = device.model;
    if (!device.serial.empty()) what += ", serial " + device.serial;
    std::cout << fmt::format("{:<10}  {:<{}}  {}: {}\n", drivers::device_kind_name(device.kind), device.uri,
                             uri_width, what, device.details);
  }
  std::string searched;
  for (const auto& transport : found.transports) {
    if (transport.searched && transport.name != "simulator") {
      searched += (searched.empty() ? "" : "; ") + transport.covers;
    }
  }
  if (!found.hardware_found()) {
    std::cout << "No hardware found"
              << (searched.empty() ? std::string(" (no hardware transport could be searched)")
                                   : " (searched: " + searched + ")")
              << ".\n";
  }
  for (const auto& transport : found.transports) {
    if (!transport.searched) std::cout << "note: " << transport.covers << " not searched: " << transport.problem << "\n";
  }
}

}  // namespace

void add_devices_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "devices", "List connected cameras, projectors and head controllers (and the built-in simulator) with the "
                 "URI that opens each");
  command->footer(
      "URIs: sim://OBJECT?preset=ci|demo|paper (simulator), gige://ADDRESS and usb3://SERIAL (GenICam cameras\n"
      "through Aravis), dlpc350://BUS:ADDRESS (projector), headctl://BUS:ADDRESS (head controller).\n"
      "Exit status 0 also when no hardware is found; the simulator is always listed.");
  command->callback([&context, exit_code] {
    run_command(context, "devices", [&context] {
      const drivers::DeviceEnumeration found = drivers::enumerate_devices();
      nlohmann::json devices = nlohmann::json::array();
      for (const auto& device : found.devices) devices.push_back(device_json(device));
      nlohmann::json transports = nlohmann::json::array();
      for (const auto& transport : found.transports) transports.push_back(transport_json(transport));
      const nlohmann::json result = {{"devices", devices},
                                     {"hardware_found", found.hardware_found()},
                                     {"transports", transports}};
      context.emit(result, [&] { print_human(found); });
      return kExitOk;
    }, exit_code);
  });
}

}  // namespace sls::cli
