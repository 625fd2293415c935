// The USB transport of the DLPC350 and head-controller drivers: one claimed interface of one
// device over libusb 1.0, with transfers that report timeouts, stalls and disconnects as
// values so each protocol layer can retry and then name the device and command in its error.
// libusb types stay in usb_connection.cpp (DESIGN.md section 2).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/interfaces/device_uri.h"
#include "sdk/core/error.h"

namespace sls::drivers::usb {

struct UsbDeviceInfo {
  int bus = 0;
  int address = 0;
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string manufacturer;  // string descriptors; empty when absent or unreadable
  std::string product;
  std::string serial;
};

// Which device to open. Zero / empty fields match anything; the first match is taken.
struct UsbSelector {
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  int bus = 0;
  int address = 0;
  std::string serial;
  std::string describe() const;  // "0451:6401 on bus 1 address 4 with serial X"
};

// A selector from a device URI's target and query, for `scheme://` URIs of USB devices:
//   ""        the first device with the default IDs      e.g. dlpc350://
//   "B:A"     bus B, address A (lsusb -s notation)       e.g. dlpc350://1:4
//   ?serial=S  ?vid=0x0451&pid=0x6401                    e.g. headctl://?serial=HC-0042
// Throws kInvalidArgument for a malformed target or query value.
UsbSelector usb_selector_from_uri(const DeviceUri& uri, std::uint16_t default_vendor_id,
                                  std::uint16_t default_product_id);

// Devices with these IDs on the system now (product_id 0: any product of the vendor).
std::vector<UsbDeviceInfo> list_usb_devices(std::uint16_t vendor_id, std::uint16_t product_id);

enum class TransferStatus {
  kOk,
  kTimeout,   // LIBUSB_ERROR_TIMEOUT: the device did not take or give data in time
  kStall,     // LIBUSB_ERROR_PIPE: the endpoint answered STALL
  kNoDevice,  // LIBUSB_ERROR_NO_DEVICE: unplugged
  kError,     // anything else (overflow, I/O error)
};

struct TransferResult {
  TransferStatus status = TransferStatus::kOk;
  std::size_t transferred = 0;
  std::string error;  // libusb's name for a failure, e.g. "LIBUSB_ERROR_PIPE"
};

// Per-command time budget: a command, retries included, fails within `command_timeout`;
// each of the `attempts` tries gets an equal share.
struct UsbRetryPolicy {
  std::chrono::milliseconds command_timeout{300};
  int attempts = 3;
  std::chrono::milliseconds attempt_timeout() const;
};

class UsbConnection {
 public:
  // Opens the first device matching `selector` and claims `interface_number` (detaching a
  // kernel driver first where one is bound). `kind` names the device in messages
  // ("DLPC350"). Throws kNotFound when nothing matches, kDevice when the device cannot be
  // opened or claimed (permissions, another program holds it).
  static std::unique_ptr<UsbConnection> open(const UsbSelector& selector, int interface_number, const std::string& kind);
  ~UsbConnection();
  UsbConnection(const UsbConnection&) = delete;
  UsbConnection& operator=(const UsbConnection&) = delete;

  const UsbDeviceInfo& info() const;
  // "DLPC350 0451:6401 on bus 1 address 4 (serial X)": how errors name the device.
  const std::string& name() const;

  // One transfer on an endpoint of the claimed interface, as interrupt or bulk transfer
  // according to the endpoint's descriptor. A timeout below 1 ms counts as 1 ms (libusb reads
  // 0 as "forever").
  TransferResult write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size,
                       std::chrono::milliseconds timeout);
  TransferResult read(std::uint8_t endpoint, std::uint8_t* data, std::size_t capacity,
                      std::chrono::milliseconds timeout);
  // CLEAR_FEATURE(ENDPOINT_HALT); false when that fails too.
  bool clear_halt(std::uint8_t endpoint);

  // What a transfer of one request attempt means for the request, the same for every driver:
  // false for success; otherwise true with the error code to raise if no retry succeeds
  // (kTimeout, or kDevice for a stall or I/O error) and a phrase for the message in *problem
  // ("endpoint 0x81 gave no reply within 100 ms"), clearing a stalled endpoint's halt first.
  // An unplugged device throws sls::Error(kDevice) at once, naming the device and `during`.
  bool transfer_failed(const TransferResult& result, std::uint8_t endpoint, std::chrono::milliseconds attempt_timeout,
                       const std::string& during, ErrorCode* failure, std::string* problem);

 private:
  struct Impl;
  explicit UsbConnection(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::drivers::usb
