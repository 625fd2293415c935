// A USB bus of emulated devices for tests: each device model (a UsbFunction) is plugged into
// a umockdev testbed with generated sysfs attributes and descriptors, and libumockdev's ioctl
// handler (UMockdevIoctlBase "handle-ioctl") answers the kernel's usbdevfs requests
// (SUBMITURB, REAPURB, DISCARDURB, CLEAR_HALT, ...) from the model. The SDK's libusb code then
// runs unmodified against it, timeouts and stalls included. The process must run under
// `umockdev-wrapper` (libumockdev-preload redirects /sys and /dev); under AddressSanitizer,
// LD_PRELOAD must name libasan before libumockdev-preload.
//
// umockdev and GLib types stay in this folder's .cpp: this header is plain C++.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "firmware-interface/models/usb_function.h"

namespace sls::fwif::models {

// True when libumockdev-preload is loaded into this process (LD_PRELOAD names it).
bool umockdev_preload_active();

class EmulatedUsbBus {
 public:
  // Creates the testbed. Throws sls::Error(kUnsupported) when the process does not run under
  // umockdev-wrapper. One bus at a time per process; create it before any libusb context
  // that should see its devices, and destroy those contexts before the bus.
  EmulatedUsbBus();
  ~EmulatedUsbBus();
  EmulatedUsbBus(const EmulatedUsbBus&) = delete;
  EmulatedUsbBus& operator=(const EmulatedUsbBus&) = delete;

  // Plugs `device` in as /dev/bus/usb/BBB/AAA (bus 1..255, address 1..127).
  void plug(std::shared_ptr<UsbFunction> device, int bus, int address);
  // usbdevfs requests answered so far (libusb polls an emulated device, so this grows while
  // the host waits).
  std::uint64_t ioctl_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::fwif::models
