// The DLPC350 (TI LightCrafter 4500 controller) USB HID command codec, after TI's "DLPC350
// Programmer's Guide" (DLPU010) and TI's reference host code (dlpc350_api.cpp, dlpc350_usb.cpp).
//
// Transport: 64-byte HID reports on the interrupt endpoints (OUT 0x01, IN 0x81); hidapi's
// leading report-ID byte is not part of what crosses the wire. A message is
//   byte 0  flags: bit 7 read (1) / write (0), bit 6 the host wants a reply, bit 5 the
//           device's error (NACK) bit in replies, bits 4:3 reserved, bits 2:0 destination
//           (0 = the projector controller)
//   byte 1  sequence number, echoed in the reply
//   byte 2-3 length of what follows (little-endian): for requests the 2 command bytes plus
//           the data; for replies the data
//   byte 4.. requests: CMD3 then CMD2 (the command word 0xCMD2CMD3 little-endian, e.g.
//           0x1A24 = bytes 24 1A), then the data; replies: the data.
// A message longer than one report continues in further 64-byte reports that carry no header
// (a request's first report holds 58 data bytes after the command, each continuation 64).
// The controller's command buffer is 512 bytes, which bounds the length.
//
// Decoding is strict and bounds-checked: a reply that is truncated, declares more bytes than
// arrived or than the controller can send, or is not a reply, throws sls::Error(kDevice).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace sls::fwif::dlpc350 {

inline constexpr std::uint16_t kVendorId = 0x0451;   // Texas Instruments
inline constexpr std::uint16_t kProductId = 0x6401;  // DLPC350
inline constexpr std::uint8_t kEndpointOut = 0x01;
inline constexpr std::uint8_t kEndpointIn = 0x81;
inline constexpr int kInterfaceNumber = 0;
inline constexpr std::size_t kReportSize = 64;
inline constexpr std::size_t kHeaderSize = 4;
inline constexpr std::size_t kMaxMessageSize = 512;  // the controller's command buffer
inline constexpr int kDmdWidth = 912;                // DLP4500 pattern-mode resolution
inline constexpr int kDmdHeight = 1140;

inline constexpr std::uint8_t kFlagRead = 0x80;
inline constexpr std::uint8_t kFlagReply = 0x40;
inline constexpr std::uint8_t kFlagError = 0x20;
inline constexpr std::uint8_t kFlagReserved = 0x18;
inline constexpr std::uint8_t kDestinationMask = 0x07;

using Report = std::array<std::uint8_t, kReportSize>;

// USB command words (CMD2 << 8 | CMD3) this SDK uses.
enum class Command : std::uint16_t {
  kPowerControl = 0x0200,         // 1 byte: 0 normal, 1 standby
  kGetVersion = 0x0205,           // read: 4 x uint32 (application, API, SW config, sequence config)
  kInputSource = 0x1A00,          // video-mode input source select
  kHardwareStatus = 0x1A0A,       // read: 1 byte
  kSystemStatus = 0x1A0B,         // read: 1 byte
  kMainStatus = 0x1A0C,           // read: 1 byte
  kLutValidate = 0x1A1A,          // write: start; read: validation status byte
  kDisplayMode = 0x1A1B,          // 1 byte: 0 video, 1 pattern
  kTrigOut1 = 0x1A1D,             // 3 bytes: invert, rising delay, falling delay
  kTrigOut2 = 0x1A1E,             // 2 bytes: invert, rising delay
  kPatternSource = 0x1A22,        // pattern display data input source: 0 video port, 3 flash
  kPatternTriggerMode = 0x1A23,   // 1 byte, TriggerMode
  kPatternStartStop = 0x1A24,     // 1 byte: 0 stop, 1 pause, 2 start
  kExposureFramePeriod = 0x1A29,  // 8 bytes: exposure us, frame period us
  kPatternConfig = 0x1A31,        // 4 bytes: entries-1, repeat, patterns per TRIG_OUT2 - 1, images-1
  kMailboxAddress = 0x1A32,       // 1 byte: 0..127
  kMailboxControl = 0x1A33,       // 1 byte: 0 close, 1 image LUT, 2 pattern LUT, 3 variable exposure
  kMailboxData = 0x1A34,          // the open mailbox's bytes, from the mailbox address on
  kNumImagesInFlash = 0x1A42,     // read: 1 byte
};

// "PAT_START_STOP (0x1A24)"; unknown words as "0xABCD".
std::string command_name(std::uint16_t command);
inline std::string command_name(Command command) { return command_name(static_cast<std::uint16_t>(command)); }

// ---- messages -------------------------------------------------------------------------
struct Request {
  bool read = false;
  bool reply_requested = true;  // reads always get a reply
  std::uint8_t sequence = 0;
  std::uint16_t command = 0;
  std::vector<std::uint8_t> data;
  bool operator==(const Request& o) const {
    return read == o.read && reply_requested == o.reply_requested && sequence == o.sequence &&
           command == o.command && data == o.data;
  }
};

struct Reply {
  bool read = false;   // the read/write bit echoed from the request
  bool error = false;  // the controller refused the command (NACK)
  std::uint8_t sequence = 0;
  std::vector<std::uint8_t> data;
  bool operator==(const Reply& o) const {
    return read == o.read && error == o.error && sequence == o.sequence && data == o.data;
  }
};

// Reports of a request; throws kInvalidArgument when it exceeds the command buffer.
std::vector<Report> encode_request(const Request& request);
// Reports of a reply (what the controller sends); throws kInvalidArgument when too long.
std::vector<Report> encode_reply(const Reply& reply);

// Reassembles messages from reports as they arrive. feed() returns the complete message after
// its last report, nothing while more are expected, and throws kDevice for a malformed first
// report (bad reserved bits, destination or length). A report shorter than 64 bytes is
// accepted as long as what it must carry is there.
class RequestAssembler {
 public:
  std::optional<Request> feed(const std::uint8_t* report, std::size_t size);
  bool in_progress() const { return expected_ != 0; }
  void reset();

 private:
  Request pending_;
  std::vector<std::uint8_t> text_;  // command bytes + data
  std::size_t expected_ = 0;
};

class ReplyAssembler {
 public:
  std::optional<Reply> feed(const std::uint8_t* report, std::size_t size);
  bool in_progress() const { return expected_ != 0; }
  void reset();

 private:
  Reply pending_;
  std::size_t expected_ = 0;
};

// A whole reply from its reports laid end to end (64 bytes each; the last may be short).
// Throws kDevice when truncated, when bytes follow the reply, or when it is not a reply.
Reply decode_reply(const std::uint8_t* bytes, std::size_t size);

// ---- typed payloads ----------------------------------------------------------------------
enum class PowerMode : std::uint8_t { kNormal = 0, kStandby = 1 };
enum class DisplayMode : std::uint8_t { kVideo = 0, kPattern = 1 };
enum class PatternSource : std::uint8_t { kVideoPort = 0, kFlash = 3 };
enum class TriggerMode : std::uint8_t {
  kVsync = 0,                // mode 0: VSYNC starts the sequence
  kInternalOrExternal = 1,   // mode 1: internal timer or TRIG_IN per LUT entry
  kAlternating = 2,          // mode 2: TRIG_IN_1 toggles a pair, TRIG_IN_2 advances
  kVariableExposure = 3,     // mode 3: mode 1 with per-pattern exposure
  kVariableExposureVsync = 4,
};
enum class SequenceAction : std::uint8_t { kStop = 0, kPause = 1, kStart = 2 };
enum class Mailbox : std::uint8_t { kClosed = 0, kImageLut = 1, kPatternLut = 2, kVariableExposureLut = 3 };

// TRIG_OUT delays: one step is 107.2 ns and code 0xBB is 0 us (TI's table: 0x00 = -20.05 us).
inline constexpr std::uint8_t kTriggerDelayZero = 0xBB;
inline constexpr double kTriggerDelayStepUs = 0.1072;
std::uint8_t trigger_delay_code(double delay_us);  // clamped to 0x00 .. 0xD5 (TI's valid range)
double trigger_delay_us(std::uint8_t code);

struct TriggerOutputConfig {
  bool active_low = false;
  std::uint8_t rising_delay = kTriggerDelayZero;
  std::uint8_t falling_delay = kTriggerDelayZero;  // TRIG_OUT1 only
  bool operator==(const TriggerOutputConfig& o) const {
    return active_low == o.active_low && rising_delay == o.rising_delay && falling_delay == o.falling_delay;
  }
};
std::vector<std::uint8_t> encode_trig_out1(const TriggerOutputConfig& config);
std::vector<std::uint8_t> encode_trig_out2(const TriggerOutputConfig& config);
TriggerOutputConfig decode_trig_out1(const std::vector<std::uint8_t>& data);
TriggerOutputConfig decode_trig_out2(const std::vector<std::uint8_t>& data);

struct ExposureTiming {
  std::uint32_t exposure_us = 8333;
  std::uint32_t frame_period_us = 8333;
  bool operator==(const ExposureTiming& o) const {
    return exposure_us == o.exposure_us && frame_period_us == o.frame_period_us;
  }
};
std::vector<std::uint8_t> encode_exposure(const ExposureTiming& timing);
ExposureTiming decode_exposure(const std::vector<std::uint8_t>& data);

struct PatternConfig {
  int lut_entries = 1;             // 1..128
  bool repeat = false;
  int patterns_per_trig_out2 = 1;  // 1..256
  int image_count = 1;             // 1..64 (flash source)
  bool operator==(const PatternConfig& o) const {
    return lut_entries == o.lut_entries && repeat == o.repeat && patterns_per_trig_out2 == o.patterns_per_trig_out2 &&
           image_count == o.image_count;
  }
};
inline constexpr int kMaxLutEntries = 128;
inline constexpr int kMaxImageLutEntries = 64;
std::vector<std::uint8_t> encode_pattern_config(const PatternConfig& config);  // kInvalidArgument out of range
PatternConfig decode_pattern_config(const std::vector<std::uint8_t>& data);

enum class LutTrigger : std::uint8_t { kInternal = 0, kExternalPositive = 1, kExternalNegative = 2, kContinue = 3 };
// LED select bits: 1 red, 2 green, 4 blue; 7 = all three (white).
inline constexpr std::uint8_t kLedWhite = 7;

// One pattern-LUT entry, 24 bits little-endian: bits 1:0 trigger, 7:2 pattern number (the
// bit plane group of the current 24-bit image: for 8-bit patterns 0 = G, 1 = R, 2 = B),
// 11:8 bit depth, 14:12 LEDs, 16 invert, 17 insert black, 18 buffer swap, 19 TRIG_OUT1 held
// from the previous pattern; bits 15 and 20..23 are reserved (0).
struct LutEntry {
  LutTrigger trigger = LutTrigger::kInternal;
  std::uint8_t pattern_number = 0;  // 0..63
  std::uint8_t bit_depth = 8;       // 1..8
  std::uint8_t leds = kLedWhite;    // 0..7
  bool invert = false;
  bool insert_black = false;
  bool buffer_swap = false;
  bool trigger_out_previous = false;
  bool operator==(const LutEntry& o) const {
    return trigger == o.trigger && pattern_number == o.pattern_number && bit_depth == o.bit_depth &&
           leds == o.leds && invert == o.invert && insert_black == o.insert_black && buffer_swap == o.buffer_swap &&
           trigger_out_previous == o.trigger_out_previous;
  }
};
inline constexpr std::size_t kLutEntrySize = 3;
std::array<std::uint8_t, kLutEntrySize> encode_lut_entry(const LutEntry& entry);  // kInvalidArgument out of range
LutEntry decode_lut_entry(const std::uint8_t* bytes);                            // kDevice for reserved bits
std::vector<std::uint8_t> encode_lut_entries(const std::vector<LutEntry>& entries);
std::vector<LutEntry> decode_lut_entries(const std::vector<std::uint8_t>& data);  // size must be a multiple of 3

// The image-index LUT as TI's reference host code sends it: a two-entry LUT goes out with its
// entries swapped (a firmware quirk TI's dlpc350_api.cpp works around); decode undoes it.
std::vector<std::uint8_t> encode_image_lut(const std::vector<std::uint8_t>& flash_images);
std::vector<std::uint8_t> decode_image_lut(const std::vector<std::uint8_t>& data);

// LUT validation status (read of 0x1A1A).
struct ValidationStatus {
  std::uint8_t bits = 0;
  static constexpr std::uint8_t kExposureInvalid = 0x01;       // exposure or frame period invalid
  static constexpr std::uint8_t kPatternNumbersInvalid = 0x02; // pattern numbers in the LUT invalid
  static constexpr std::uint8_t kTrigOut1Overlap = 0x04;       // warning: continuous TRIG_OUT1 / black overlap
  static constexpr std::uint8_t kPostVectorMissing = 0x08;     // warning: no black before an external trigger
  static constexpr std::uint8_t kPeriodTooClose = 0x10;        // warning: period - exposure < 230 us
  static constexpr std::uint8_t kBusy = 0x80;                  // validation still running
  bool busy() const { return (bits & kBusy) != 0; }
  bool valid() const { return (bits & (kExposureInvalid | kPatternNumbersInvalid)) == 0; }
  std::string describe() const;  // "exposure or frame period invalid; ..." or "valid"
};

struct HardwareStatus {
  std::uint8_t bits = 0;
  bool initialized() const { return (bits & 0x01) != 0; }
  bool drc_error() const { return (bits & 0x04) != 0; }
  bool forced_swap_error() const { return (bits & 0x08) != 0; }
  bool sequence_abort() const { return (bits & 0x40) != 0; }
  bool sequence_error() const { return (bits & 0x80) != 0; }
  std::string describe() const;
};
struct SystemStatus {
  std::uint8_t bits = 0;
  bool memory_test_passed() const { return (bits & 0x01) != 0; }
};
struct MainStatus {
  std::uint8_t bits = 0;
  bool dmd_parked() const { return (bits & 0x01) != 0; }
  bool sequence_running() const { return (bits & 0x02) != 0; }
  bool buffer_frozen() const { return (bits & 0x04) != 0; }
  bool gamma_correction() const { return (bits & 0x08) != 0; }
};

// GET_VERSION: each word is major (bits 31:24), minor (23:16), patch (15:0).
struct Version {
  std::uint32_t application = 0;
  std::uint32_t api = 0;
  std::uint32_t software_config = 0;
  std::uint32_t sequence_config = 0;
  static std::string format(std::uint32_t word);  // "3.0.0"
  bool operator==(const Version& o) const {
    return application == o.application && api == o.api && software_config == o.software_config &&
           sequence_config == o.sequence_config;
  }
};
inline constexpr std::size_t kVersionSize = 16;
std::vector<std::uint8_t> encode_version(const Version& version);
Version decode_version(const std::vector<std::uint8_t>& data);

// The single byte of a one-byte read (status, modes); kDevice when the reply has none.
std::uint8_t decode_byte(const std::vector<std::uint8_t>& data, Command command);

}  // namespace sls::fwif::dlpc350
