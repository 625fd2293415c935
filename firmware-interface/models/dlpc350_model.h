// Emulated DLPC350 firmware: the projector controller of a LightCrafter 4500 as the host's
// USB HID traffic sees it. It keeps the controller's state (power, display mode, pattern
// source, trigger mode and outputs, exposure, the pattern and image LUTs written through the
// mailbox, validation, the sequencer) and answers reads, following TI's DLPC350 Programmer's
// Guide; where the guide leaves behaviour open the model is stricter than the hardware (it
// refuses sequence settings while the sequencer runs, as the guide tells hosts not to do).
// The pattern on the DMD follows the LUT on the device clock, so a camera emulation can render
// what is projected at any moment.
#pragma once

#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "firmware-interface/dlpc350/dlpc350_codec.h"
#include "firmware-interface/models/usb_function.h"

namespace sls::fwif::models {

struct Dlpc350ModelOptions {
  std::string serial = "LCR4500-EMU-0001";
  dlpc350::Version version{0x03000000u, 0x02000000u, 0x01000000u, 0x01000000u};  // application 3.0.0
  int flash_images = 16;           // 24-bit images in flash (NUM_IMAGE_IN_FLASH)
  int validation_busy_reads = 2;   // LUT_VALID reads that report "busy" after a validate
};

// What the DMD shows now.
struct DisplayedPattern {
  int lut_index = 0;       // entry of the pattern LUT
  int flash_image = 0;     // flash image it comes from
  int pattern_number = 0;  // bit-plane group of that image (8-bit: 0 = G, 1 = R, 2 = B)
  int bit_depth = 8;
  bool inverted = false;
  std::uint8_t leds = dlpc350::kLedWhite;
};

class Dlpc350Model final : public UsbFunction {
 public:
  explicit Dlpc350Model(Dlpc350ModelOptions options = {}, DeviceClock clock = steady_device_clock());

  UsbIdentity identity() const override;

  struct State {
    dlpc350::PowerMode power = dlpc350::PowerMode::kNormal;
    dlpc350::DisplayMode display_mode = dlpc350::DisplayMode::kVideo;
    dlpc350::PatternSource pattern_source = dlpc350::PatternSource::kVideoPort;
    dlpc350::TriggerMode trigger_mode = dlpc350::TriggerMode::kVsync;
    dlpc350::TriggerOutputConfig trig_out1;
    dlpc350::TriggerOutputConfig trig_out2;
    dlpc350::ExposureTiming exposure;
    dlpc350::PatternConfig pattern_config;
    std::vector<dlpc350::LutEntry> pattern_lut;  // all 128 entries
    std::vector<std::uint8_t> image_lut;         // all 64 entries
    dlpc350::Mailbox mailbox = dlpc350::Mailbox::kClosed;
    int mailbox_address = 0;
    bool validated = false;  // the current settings passed validation
    dlpc350::SequenceAction sequence = dlpc350::SequenceAction::kStop;
  };
  State state() const;
  // The pattern on the DMD now; nothing while the sequencer is stopped, has finished a
  // non-repeating sequence, or the controller is in standby.
  std::optional<DisplayedPattern> displayed_pattern() const;
  // Patterns displayed since power-on, one TRIG_OUT1 pulse each.
  std::uint64_t trigger_out1_pulses() const;
  // Every complete request the host sent, in order, to check the bytes on the wire.
  std::vector<dlpc350::Request> requests() const;
  // The OUT reports themselves (zero-padded to 64 bytes), in order.
  std::vector<dlpc350::Report> reports() const;
  void clear_requests();
  // Answer `command` with the error bit from now on, like firmware that refuses it.
  void refuse(dlpc350::Command command);

 protected:
  TransferOutcome handle_write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size) override;
  TransferOutcome handle_read(std::uint8_t endpoint, std::size_t capacity, std::vector<std::uint8_t>& out) override;

 private:
  // All private functions run with mutex_ held.
  void execute(const dlpc350::Request& request);
  // Returns the reply data of a read, or nothing to NACK it.
  std::optional<std::vector<std::uint8_t>> execute_read(std::uint16_t command);
  // Returns false to NACK the write.
  bool execute_write(std::uint16_t command, const std::vector<std::uint8_t>& data);
  bool write_mailbox(const std::vector<std::uint8_t>& data);
  std::uint8_t validate() const;
  void queue_reply(const dlpc350::Reply& reply);
  // Frames displayed since the sequencer last started (or the paused frame count).
  std::int64_t frames_since_start() const;
  bool sequence_finished() const;
  std::optional<DisplayedPattern> displayed_locked() const;
  std::uint64_t pulses_locked() const;
  void stop_sequence();

  const Dlpc350ModelOptions options_;
  const DeviceClock clock_;
  mutable std::mutex mutex_;
  State state_;
  dlpc350::RequestAssembler assembler_;
  std::deque<dlpc350::Report> replies_;
  std::vector<dlpc350::Request> requests_;
  std::vector<dlpc350::Report> reports_;
  std::set<std::uint16_t> refused_;
  std::uint8_t validation_bits_ = 0;
  int validation_busy_left_ = 0;
  std::int64_t started_at_us_ = 0;       // device time of the last start
  std::int64_t frames_before_start_ = 0; // frames already shown when a paused sequence resumed
  std::uint64_t pulses_before_run_ = 0;  // TRIG_OUT1 pulses of earlier runs
};

}  // namespace sls::fwif::models
