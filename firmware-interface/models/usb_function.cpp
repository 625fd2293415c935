#include "firmware-interface/models/usb_function.h"

namespace sls::fwif::models {

DeviceClock steady_device_clock() {
  return [] {
    return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
}

TransferOutcome UsbFunction::write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size) {
  TransferOutcome outcome = TransferOutcome::kDone;
  if (injected(true, &outcome)) return outcome;
  return handle_write(endpoint, data, size);
}

TransferOutcome UsbFunction::read(std::uint8_t endpoint, std::size_t capacity, std::vector<std::uint8_t>& out) {
  TransferOutcome outcome = TransferOutcome::kPending;
  if (injected(false, &outcome)) return outcome;
  return handle_read(endpoint, capacity, out);
}

void UsbFunction::clear_halt(std::uint8_t) {
  std::lock_guard<std::mutex> lock(fault_mutex_);
  halted_ = false;
}

void UsbFunction::set_behaviour(Behaviour behaviour) {
  std::lock_guard<std::mutex> lock(fault_mutex_);
  behaviour_ = behaviour;
  if (behaviour == Behaviour::kNormal) halted_ = false;
}

Behaviour UsbFunction::behaviour() const {
  std::lock_guard<std::mutex> lock(fault_mutex_);
  return behaviour_;
}

bool UsbFunction::injected(bool is_out, TransferOutcome* outcome) {
  std::lock_guard<std::mutex> lock(fault_mutex_);
  switch (behaviour_) {
    case Behaviour::kUnplugged:
      *outcome = TransferOutcome::kNoDevice;
      return true;
    case Behaviour::kStall:
      *outcome = TransferOutcome::kStall;
      return true;
    case Behaviour::kStallOnce:
      // A real halt persists until the host clears it, so the endpoint stays halted after this.
      behaviour_ = Behaviour::kNormal;
      halted_ = true;
      *outcome = TransferOutcome::kStall;
      return true;
    case Behaviour::kSilent:
      // Hung firmware whose USB core still ACKs: writes vanish, reads never complete.
      *outcome = is_out ? TransferOutcome::kDone : TransferOutcome::kPending;
      return true;
    case Behaviour::kNormal:
      break;
  }
  if (halted_) {
    *outcome = TransferOutcome::kStall;
    return true;
  }
  return false;
}

}  // namespace sls::fwif::models
