#include "drivers/usb/usb_scanner_devices.h"

#include <fmt/format.h>

#include <algorithm>

#include "firmware-interface/dlpc350/dlpc350_codec.h"
#include "firmware-interface/headctl/headctl_protocol.h"

namespace sls::drivers::usb {
namespace {

UsbScannerDevice make_entry(UsbScannerDeviceKind kind, const char* scheme, const UsbDeviceInfo& info) {
  UsbScannerDevice device;
  device.kind = kind;
  device.uri = fmt::format("{}://{}:{}", scheme, info.bus, info.address);
  if (kind == UsbScannerDeviceKind::kHeadController &&
      (info.vendor_id != HEADCTL_USB_VENDOR_ID || info.product_id != HEADCTL_USB_PRODUCT_ID)) {
    device.uri += fmt::format("?vid=0x{:04x}&pid=0x{:04x}", info.vendor_id, info.product_id);  // an OEM's own IDs
  }
  std::string detail = fmt::format("{} {}", info.manufacturer, info.product);
  if (!info.serial.empty()) detail += ", serial " + info.serial;
  device.description = fmt::format("{} ({:04x}:{:04x}{})", usb_scanner_device_kind_name(kind), info.vendor_id,
                                   info.product_id, detail == " " ? std::string() : ", " + detail);
  device.usb = info;
  return device;
}

}  // namespace

const char* usb_scanner_device_kind_name(UsbScannerDeviceKind kind) {
  return kind == UsbScannerDeviceKind::kDlpc350Projector ? "DLPC350 projector" : "head controller";
}

std::vector<UsbScannerDevice> list_usb_scanner_devices(
    const std::vector<std::pair<std::uint16_t, std::uint16_t>>& head_controller_ids) {
  std::vector<UsbScannerDevice> devices;
  for (const UsbDeviceInfo& info : list_usb_devices(fwif::dlpc350::kVendorId, fwif::dlpc350::kProductId)) {
    devices.push_back(make_entry(UsbScannerDeviceKind::kDlpc350Projector, "dlpc350", info));
  }
  std::vector<std::pair<std::uint16_t, std::uint16_t>> ids = {{HEADCTL_USB_VENDOR_ID, HEADCTL_USB_PRODUCT_ID}};
  for (const auto& id : head_controller_ids) {
    if (std::find(ids.begin(), ids.end(), id) == ids.end()) ids.push_back(id);
  }
  for (const auto& [vendor, product] : ids) {
    for (const UsbDeviceInfo& info : list_usb_devices(vendor, product)) {
      devices.push_back(make_entry(UsbScannerDeviceKind::kHeadController, "headctl", info));
    }
  }
  std::sort(devices.begin(), devices.end(), [](const UsbScannerDevice& a, const UsbScannerDevice& b) {
    return std::make_pair(a.usb.bus, a.usb.address) < std::make_pair(b.usb.bus, b.usb.address);
  });
  return devices;
}

}  // namespace sls::drivers::usb
