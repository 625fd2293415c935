// What an emulated USB device looks like to a bus: its descriptors and what it does with
// transfers on its endpoints. The device models (emulated firmware) implement it as pure C++
// state machines fed with bytes, testable on their own; the umockdev adapter
// (models/umockdev) puts any of them behind real libusb, and its fault injection (stall,
// silence, unplug) lives here so every model has the same failure modes.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

namespace sls::fwif::models {

enum class EndpointType : std::uint8_t { kBulk = 2, kInterrupt = 3 };

struct EndpointDescription {
  std::uint8_t address = 0;  // bit 7 set for IN
  EndpointType type = EndpointType::kBulk;
  std::uint16_t max_packet_size = 64;
  std::uint8_t interval = 0;  // interrupt endpoints: polling interval (frames)
};

struct UsbIdentity {
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::uint16_t device_release = 0x0100;  // bcdDevice
  std::string manufacturer;
  std::string product;
  std::string serial;
  std::uint8_t interface_class = 0xFF;
  std::uint8_t interface_subclass = 0;
  std::uint8_t interface_protocol = 0;
  std::vector<EndpointDescription> endpoints;
};

enum class TransferOutcome {
  kDone,      // completed (an IN transfer got data)
  kPending,   // the device NAKs for now (IN: nothing to send yet)
  kStall,     // the endpoint answers STALL (host sees LIBUSB_ERROR_PIPE)
  kNoDevice,  // the device is gone (host sees LIBUSB_ERROR_NO_DEVICE)
};

// How a device misbehaves, for tests of the host's error paths.
enum class Behaviour {
  kNormal,
  kStallOnce,  // the next transfer stalls; after the host clears the halt all is normal
  kStall,      // every transfer stalls, clearing the halt does not help (hung firmware)
  kSilent,     // OUT transfers are accepted and dropped, nothing ever comes back
  kUnplugged,  // every transfer fails as if the cable were pulled
};

// Microseconds on the device's clock. Models read time through it so tests can drive it.
using DeviceClock = std::function<std::int64_t()>;
DeviceClock steady_device_clock();

class UsbFunction {
 public:
  virtual ~UsbFunction() = default;

  virtual UsbIdentity identity() const = 0;

  // The host wrote `size` bytes to OUT endpoint `endpoint`. kPending keeps the transfer
  // waiting (NAK); the bus offers it again later.
  TransferOutcome write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size);
  // The host asks for up to `capacity` bytes from IN endpoint `endpoint`; on kDone `out`
  // holds what the device sent.
  TransferOutcome read(std::uint8_t endpoint, std::size_t capacity, std::vector<std::uint8_t>& out);
  // USB CLEAR_FEATURE(ENDPOINT_HALT) from the host.
  void clear_halt(std::uint8_t endpoint);

  void set_behaviour(Behaviour behaviour);
  Behaviour behaviour() const;

 protected:
  // Implemented by the models, called with the fault injection already applied. A model
  // guards its state with its own mutex: the bus calls from its ioctl thread while a test
  // inspects the model from another.
  virtual TransferOutcome handle_write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size) = 0;
  virtual TransferOutcome handle_read(std::uint8_t endpoint, std::size_t capacity, std::vector<std::uint8_t>& out) = 0;

 private:
  // Returns true (with the outcome) when fault injection decides the transfer.
  bool injected(bool is_out, TransferOutcome* outcome);

  mutable std::mutex fault_mutex_;
  Behaviour behaviour_ = Behaviour::kNormal;
  bool halted_ = false;  // one halt for all endpoints: enough for the host's error paths
};

}  // namespace sls::fwif::models
