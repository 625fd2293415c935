// Emulated head-controller firmware: a reference implementation of PROTOCOL.md behind the
// USB bulk endpoints. It drives a simulated stepper turntable (steps per revolution, a home
// switch at an unknown step, moves that take steps / speed seconds on the device clock), trigger
// outputs with per-output pulse counters, temperature sensors, the error log, and the
// protocol's duplicate detection (a retried request is answered from the cached reply, never
// executed twice). Faults can be injected for the host's error paths.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "firmware-interface/headctl/headctl_codec.h"
#include "firmware-interface/models/usb_function.h"

namespace sls::fwif::models {

struct HeadctlModelOptions {
  std::uint16_t vendor_id = HEADCTL_USB_VENDOR_ID;
  std::uint16_t product_id = HEADCTL_USB_PRODUCT_ID;
  std::string serial = "HC-EMU-0001";
  std::string model = "slscan head controller";
  std::uint8_t firmware_major = 1;
  std::uint8_t firmware_minor = 0;
  std::uint8_t firmware_patch = 0;
  std::uint8_t hardware_revision = 2;
  std::uint8_t trigger_outputs = 4;
  std::uint32_t steps_per_revolution = 6400;       // 200-step motor at 1/32 microstepping
  std::uint32_t default_speed_steps_per_s = 6400;  // one revolution per second
  std::uint32_t max_speed_steps_per_s = 64000;
  std::uint32_t home_switch_step = 1234;  // where the index is, counted from the power-on position
  std::vector<headctl::Temperature> temperatures{{0, 3150}, {1, 4210}};  // board, motor driver
  std::int16_t over_temperature_centi_celsius = 8500;
};

class HeadctlModel final : public UsbFunction {
 public:
  explicit HeadctlModel(HeadctlModelOptions options = {}, DeviceClock clock = steady_device_clock());

  UsbIdentity identity() const override;

  // The turntable as the board sees it now.
  headctl::TurntableStatusReply turntable();
  // Pulses fired on an output since power-on.
  std::uint64_t pulses_on_output(int output);
  // Requests received (retries included) and executed (retries answered from the cache
  // excluded), in order.
  std::vector<headctl::MessageType> received() const;
  std::vector<headctl::MessageType> executed() const;

  // Fault injection.
  void set_temperature(std::uint8_t sensor, double celsius);
  void latch_fault(headctl::Fault fault);         // e.g. a stepper driver fault now
  void stall_next_move_after(std::uint32_t steps);  // the next move stops there with MOTOR_STALL
  void remove_home_switch(bool removed);           // homing finds no index: HOME_NOT_FOUND
  void drop_next_replies(int count);               // execute, but lose the reply on the way
  void corrupt_next_replies(int count);            // execute, send the reply with a bad CRC

 protected:
  TransferOutcome handle_write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size) override;
  TransferOutcome handle_read(std::uint8_t endpoint, std::size_t capacity, std::vector<std::uint8_t>& out) override;

 private:
  struct Motion {
    std::int64_t start_us = 0;
    std::int64_t start_absolute = 0;  // steps from the power-on position
    std::int64_t distance = 0;        // signed steps
    std::uint32_t speed = 0;
    bool homing = false;
    std::optional<std::uint32_t> stall_after;
  };
  struct Armed {
    std::uint8_t output_mask = 0;
    headctl::TriggerSource source = headctl::TriggerSource::kHost;
    std::uint16_t count = 0;
    std::uint32_t period_us = 0;
    std::int64_t armed_at_us = 0;
    std::uint16_t fired = 0;  // host source; the timer source derives it from the clock
  };

  // All private functions run with mutex_ held.
  headctl::Reply execute(const headctl::Request& request, std::uint8_t sequence);
  headctl::Reply refuse(headctl::DeviceError code, std::uint32_t detail, std::string text);
  void advance();  // brings motion, timer pulses and temperature faults up to the clock
  void fire_pulses(std::uint8_t mask, std::uint64_t count);
  std::int64_t absolute_now() const;  // stepper position from power-on, moving or not
  std::uint32_t position_locked() const;
  std::uint32_t wrap(std::int64_t steps) const;
  headctl::TurntableStatusReply turntable_locked() const;
  void queue(std::vector<std::uint8_t> frame);

  const HeadctlModelOptions options_;
  const DeviceClock clock_;
  mutable std::mutex mutex_;
  std::deque<std::vector<std::uint8_t>> replies_;
  // Duplicate detection: the last request frame and the reply sent for it.
  std::vector<std::uint8_t> last_request_;
  std::vector<std::uint8_t> last_reply_;
  std::vector<headctl::MessageType> received_;
  std::vector<headctl::MessageType> executed_;
  std::deque<headctl::ErrorLogEntry> error_log_;
  std::uint8_t current_type_ = 0;
  std::uint8_t current_sequence_ = 0;

  std::int64_t absolute_step_ = 0;  // stepper position from power-on, when not moving
  std::int64_t zero_absolute_ = 0;  // absolute step of the home index (0 deg)
  bool homed_ = false;
  std::optional<Motion> motion_;
  std::uint32_t target_step_ = 0;
  std::uint32_t speed_ = 0;
  headctl::Fault fault_ = headctl::Fault::kNone;
  std::optional<std::uint32_t> stall_next_move_after_;
  bool home_switch_removed_ = false;

  std::array<headctl::TriggerConfigureRequest, HEADCTL_MAX_TRIGGER_OUTPUTS> outputs_{};
  std::array<std::uint64_t, HEADCTL_MAX_TRIGGER_OUTPUTS> pulses_{};
  std::uint32_t total_pulses_ = 0;
  std::optional<Armed> armed_;
  std::vector<headctl::Temperature> temperatures_;

  int drop_replies_ = 0;
  int corrupt_replies_ = 0;
};

}  // namespace sls::fwif::models
