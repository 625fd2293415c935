// The scanner's USB devices connected now: DLPC350 projectors and head controllers, as plain
// structs with the URI that opens each (for `sls devices` and device pickers).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "drivers/usb/usb_connection.h"

namespace sls::drivers::usb {

enum class UsbScannerDeviceKind { kDlpc350Projector, kHeadController };

struct UsbScannerDevice {
  UsbScannerDeviceKind kind = UsbScannerDeviceKind::kDlpc350Projector;
  std::string uri;          // "dlpc350://1:4", "headctl://1:5"
  std::string description;  // "DLPC350 projector (Texas Instruments DLPC350, serial X)"
  UsbDeviceInfo usb;
};

const char* usb_scanner_device_kind_name(UsbScannerDeviceKind kind);  // "projector", "head controller"

// DLPC350s (0451:6401) and head controllers (the protocol's development IDs plus any
// `head_controller_ids` an OEM build uses), in bus order.
std::vector<UsbScannerDevice> list_usb_scanner_devices(
    const std::vector<std::pair<std::uint16_t, std::uint16_t>>& head_controller_ids = {});

}  // namespace sls::drivers::usb
