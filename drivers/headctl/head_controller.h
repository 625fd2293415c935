// The slscan head controller (trigger outputs and turntable stepper, protocol in
// firmware-interface/headctl/PROTOCOL.md) over USB bulk endpoints: a drivers::Turntable plus
// the trigger commands the capture sequencer needs.
//
// Each request is one bulk transfer; the reply is matched by its sequence number. A request
// that times out, whose reply is corrupt or that the board reports as BAD_FRAME is sent again,
// byte for byte, so the board answers a retry from its cache instead of executing it twice.
// When HeadControllerOptions::retry.command_timeout passes without a reply the call throws
// sls::Error(kTimeout); a stalled endpoint, a disconnect or a board that refuses the request
// throw kDevice (kBusy, kInvalidArgument, kVersionMismatch where the board's error says so).
// Every message names the device and the request.
//
// Thread-safe: requests from several threads go on the wire one at a time.
#pragma once

#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "drivers/interfaces/turntable.h"
#include "drivers/usb/usb_connection.h"
#include "firmware-interface/headctl/headctl_codec.h"

namespace sls::drivers {

struct HeadControllerOptions {
  usb::UsbRetryPolicy retry{std::chrono::milliseconds{3 * HEADCTL_HOST_ATTEMPT_TIMEOUT_MS},
                            static_cast<int>(HEADCTL_HOST_MAX_ATTEMPTS)};
  std::chrono::milliseconds poll_interval{2};  // turntable status polls while it moves
};

class HeadController final : public Turntable {
 public:
  static std::unique_ptr<HeadController> open(const usb::UsbSelector& selector, HeadControllerOptions options = {});
  // headctl://  headctl://BUS:ADDRESS  headctl://?serial=S  headctl://?vid=0x1234&pid=0x5678
  static std::unique_ptr<HeadController> open(const std::string& uri, HeadControllerOptions options = {});
  ~HeadController() override;

  const std::string& name() const;
  const std::string& uri() const;
  const fwif::headctl::IdentifyReply& identity() const;

  // Triggers.
  void configure_trigger(const fwif::headctl::TriggerConfigureRequest& config);
  void arm_triggers(const fwif::headctl::TriggerArmRequest& sequence);
  fwif::headctl::TriggerFireReply fire_trigger();
  fwif::headctl::TriggerStatusReply trigger_status();
  void disarm_triggers();

  // drivers::Turntable.
  void home(std::chrono::milliseconds timeout) override;
  void move_to_deg(double angle_deg, std::chrono::milliseconds timeout) override;
  double position_deg() const override;
  int steps_per_revolution() const override;

  // Moves to `step` and waits; kTimeout (after stopping the table) when it is not there in
  // time, kDevice when the board reports a fault.
  void move_to_step(std::uint32_t step, fwif::headctl::Direction direction, std::chrono::milliseconds timeout,
                    std::uint32_t speed_steps_per_s = 0);
  fwif::headctl::TurntableStatusReply turntable_status() const;
  void stop_turntable();

  std::vector<fwif::headctl::Temperature> temperatures();
  std::vector<fwif::headctl::ErrorLogEntry> error_log();
  void clear_errors();

  // One request, retried as the file comment says; returns the typed reply.
  fwif::headctl::Reply transact(const fwif::headctl::Request& request) const;

 private:
  HeadController(std::unique_ptr<usb::UsbConnection> connection, HeadControllerOptions options, std::string uri);
  void require_turntable() const;
  template <typename T>
  T expect(const fwif::headctl::Request& request) const;
  // Polls the status until `done` or a fault; kTimeout (after stopping the table) once
  // `deadline` passes, naming the caller's `timeout`.
  template <typename Done>
  void wait_for_turntable(Done done, std::chrono::steady_clock::time_point deadline,
                          std::chrono::milliseconds timeout, const std::string& goal);

  std::unique_ptr<usb::UsbConnection> connection_;
  const HeadControllerOptions options_;
  const std::string uri_;
  fwif::headctl::IdentifyReply identity_;
  mutable std::mutex mutex_;  // one request on the wire at a time
  mutable std::uint8_t next_sequence_ = 0;
};

}  // namespace sls::drivers
