// The DLPC350 projector (TI LightCrafter 4500) over USB HID, as a drivers::Projector.
//
// Patterns come from the controller's flash: pattern i of a set is the 8-bit bit-plane group
// i % 3 (G, R, B) of flash image first_flash_image + i / 3, so the set's images must be in
// flash in that order (dlpc350_flash_layout() says which pattern goes where). The driver
// writes the pattern LUT and the image LUT through the mailbox, validates them, and runs the
// sequencer in pattern mode with internal triggers; TRIG_OUT1 pulses at the start of every
// pattern (the cameras' hardware trigger), TRIG_OUT2 once per sequence.
//
// Two ways to project: show_pattern(i) puts a one-entry repeating LUT of pattern i on the DMD
// (software-paced capture), play_sequence() runs the whole loaded set once at the exposure
// timing (hardware-triggered capture at up to 120 Hz for 8-bit patterns).
//
// Every command is acknowledged by the controller and checked; a command that is not
// answered within Dlpc350Options::retry.command_timeout (retries included) throws
// sls::Error(kTimeout), a stalled endpoint or a refused command throws kDevice; each message
// names the device and the command.
//
// Not thread-safe: one thread (the capture sequencer) drives a projector.
#pragma once

#include <array>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "drivers/interfaces/projector.h"
#include "drivers/usb/usb_connection.h"
#include "firmware-interface/dlpc350/dlpc350_codec.h"

namespace sls::drivers {

struct Dlpc350Options {
  usb::UsbRetryPolicy retry{std::chrono::milliseconds{600}, 3};
  // How long LUT validation and the start of the sequencer may take.
  std::chrono::milliseconds settle_timeout{2000};
  fwif::dlpc350::ExposureTiming timing{8333, 8333};  // 8-bit patterns at 120 Hz
  fwif::dlpc350::TriggerOutputConfig trig_out1{};     // active high, no delay
  fwif::dlpc350::TriggerOutputConfig trig_out2{};
  std::uint8_t leds = fwif::dlpc350::kLedWhite;
  int first_flash_image = 0;  // where the pattern set's images start in flash
};

// Where pattern `index` of a set lives in flash (see the file comment).
struct Dlpc350FlashSlot {
  int flash_image = 0;
  int pattern_number = 0;  // 0 = G, 1 = R, 2 = B bit planes
};
Dlpc350FlashSlot dlpc350_flash_slot(int index, int first_flash_image);
// The inverse: the pattern index a flash slot holds for a set loaded at `first_flash_image`
// (e.g. to render what an emulated DMD shows); -1 for a slot before the set's images.
int dlpc350_pattern_index(const Dlpc350FlashSlot& slot, int first_flash_image);
// The flash images a set needs, with the pattern index of each of their G, R, B planes (-1:
// unused).
std::vector<std::array<int, 3>> dlpc350_flash_layout(const PatternSet& set);

class Dlpc350Projector final : public Projector {
 public:
  static std::unique_ptr<Dlpc350Projector> open(const usb::UsbSelector& selector, Dlpc350Options options = {});
  // dlpc350://  dlpc350://BUS:ADDRESS  dlpc350://?serial=S (see usb_selector_from_uri).
  static std::unique_ptr<Dlpc350Projector> open(const std::string& uri, Dlpc350Options options = {});
  ~Dlpc350Projector() override;

  // drivers::Projector
  ProjectorInfo info() const override;
  // Validates the set (912 x 1140, at most 128 patterns, its images in flash), then writes
  // and validates the LUT of the whole sequence. kInvalidArgument when the set does not fit.
  void load_patterns(const PatternSet& patterns) override;
  const PatternSet& patterns() const override;
  void show_pattern(int index) override;
  int current_pattern() const override;
  void go_dark() override;

  // Runs the loaded set once on the controller's clock; current_pattern() then follows the
  // host clock until the sequence ends.
  void play_sequence();

  // Controller commands, each one acknowledged round trip.
  fwif::dlpc350::Version version();
  struct Status {
    fwif::dlpc350::HardwareStatus hardware;
    fwif::dlpc350::SystemStatus system;
    fwif::dlpc350::MainStatus main;
  };
  Status status();
  fwif::dlpc350::PowerMode power();
  void set_power(fwif::dlpc350::PowerMode mode);
  void set_display_mode(fwif::dlpc350::DisplayMode mode);
  void set_pattern_source(fwif::dlpc350::PatternSource source);
  void set_trigger_mode(fwif::dlpc350::TriggerMode mode);
  void configure_trigger_output(int output, const fwif::dlpc350::TriggerOutputConfig& config);  // 1 or 2
  void set_exposure(const fwif::dlpc350::ExposureTiming& timing);
  fwif::dlpc350::ExposureTiming exposure();
  // PAT_CONFIG, then the pattern LUT and the image LUT through the mailbox.
  void write_luts(const fwif::dlpc350::PatternConfig& config, const std::vector<fwif::dlpc350::LutEntry>& entries,
                  const std::vector<std::uint8_t>& flash_images);
  std::vector<fwif::dlpc350::LutEntry> read_pattern_lut(int entries);
  // Starts validation and polls it; throws kDevice describing the problem when invalid.
  fwif::dlpc350::ValidationStatus validate();
  void sequence(fwif::dlpc350::SequenceAction action);
  int flash_image_count();

  const std::string& name() const;

 private:
  Dlpc350Projector(std::unique_ptr<usb::UsbConnection> connection, Dlpc350Options options, std::string uri);
  // One command with retries. Returns the reply data; throws as the file comment says.
  std::vector<std::uint8_t> transact(fwif::dlpc350::Command command, bool read, const std::vector<std::uint8_t>& data,
                                     int attempts);
  std::vector<std::uint8_t> read(fwif::dlpc350::Command command);
  void write(fwif::dlpc350::Command command, const std::vector<std::uint8_t>& data);
  void write_mailbox(fwif::dlpc350::Mailbox mailbox, const std::vector<std::uint8_t>& data);
  void prepare_pattern_mode();
  void load_full_sequence();
  void wait_until_running();

  std::unique_ptr<usb::UsbConnection> connection_;
  const Dlpc350Options options_;
  const std::string uri_;
  std::string firmware_;
  std::uint8_t next_sequence_ = 0;
  PatternSet patterns_;
  bool lut_holds_sequence_ = false;  // the controller's LUT is the whole set (not one pattern)
  int shown_ = -1;
  std::optional<std::chrono::steady_clock::time_point> playing_since_;
};

}  // namespace sls::drivers
