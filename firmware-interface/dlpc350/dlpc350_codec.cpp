#include "firmware-interface/dlpc350/dlpc350_codec.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "firmware-interface/wire_bytes.h"
#include "sdk/core/error.h"

namespace sls::fwif::dlpc350 {
namespace {

constexpr std::size_t kFirstReportText = kReportSize - kHeaderSize;  // 60

void check_flags(std::uint8_t flags, const char* what) {
  if ((flags & kFlagReserved) != 0) {
    throw_error(ErrorCode::kDevice, "DLPC350 {}: reserved flag bits set (flags 0x{:02x})", what, flags);
  }
  if ((flags & kDestinationMask) != 0) {
    throw_error(ErrorCode::kDevice, "DLPC350 {}: destination {} is not the projector controller (flags 0x{:02x})",
                what, flags & kDestinationMask, flags);
  }
}

std::vector<Report> split_into_reports(std::uint8_t flags, std::uint8_t sequence, const std::vector<std::uint8_t>& text) {
  std::vector<Report> reports;
  Report first{};
  first[0] = flags;
  first[1] = sequence;
  first[2] = static_cast<std::uint8_t>(text.size() & 0xFF);
  first[3] = static_cast<std::uint8_t>(text.size() >> 8);
  const std::size_t head = std::min(text.size(), kFirstReportText);
  std::copy(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(head), first.begin() + kHeaderSize);
  reports.push_back(first);
  for (std::size_t offset = head; offset < text.size(); offset += kReportSize) {
    Report next{};
    const std::size_t count = std::min(kReportSize, text.size() - offset);
    std::copy(text.begin() + static_cast<std::ptrdiff_t>(offset),
              text.begin() + static_cast<std::ptrdiff_t>(offset + count), next.begin());
    reports.push_back(next);
  }
  return reports;
}

// Starts a message from its first report; returns the bytes still expected after it.
std::size_t start_message(const std::uint8_t* report, std::size_t size, const char* what, std::uint8_t* flags,
                          std::uint8_t* sequence, std::vector<std::uint8_t>* text) {
  if (size < kHeaderSize) {
    throw_error(ErrorCode::kDevice, "DLPC350 {}: report of {} byte(s) is shorter than the {}-byte header", what, size,
                kHeaderSize);
  }
  if (size > kReportSize) {
    throw_error(ErrorCode::kDevice, "DLPC350 {}: report of {} bytes exceeds {}", what, size, kReportSize);
  }
  *flags = report[0];
  check_flags(*flags, what);
  *sequence = report[1];
  const std::size_t length = static_cast<std::size_t>(report[2] | (report[3] << 8));
  if (length > kMaxMessageSize) {
    throw_error(ErrorCode::kDevice, "DLPC350 {}: length {} exceeds the controller's {}-byte buffer", what, length,
                kMaxMessageSize);
  }
  const std::size_t head = std::min(length, kFirstReportText);
  if (size < kHeaderSize + head) {
    throw_error(ErrorCode::kDevice, "DLPC350 {}: truncated: the header announces {} byte(s), the report holds {}", what,
                length, size - kHeaderSize);
  }
  text->assign(report + kHeaderSize, report + kHeaderSize + head);
  return length - head;
}

// Appends a continuation report; returns the bytes still expected.
std::size_t continue_message(const std::uint8_t* report, std::size_t size, std::size_t expected, const char* what,
                             std::vector<std::uint8_t>* text) {
  const std::size_t count = std::min(expected, kReportSize);
  if (size < count || size > kReportSize) {
    throw_error(ErrorCode::kDevice, "DLPC350 {}: continuation report of {} byte(s), {} expected", what, size, count);
  }
  text->insert(text->end(), report, report + count);
  return expected - count;
}

}  // namespace

std::string command_name(std::uint16_t command) {
  const char* name = nullptr;
  switch (static_cast<Command>(command)) {
    case Command::kPowerControl: name = "POWER_CONTROL"; break;
    case Command::kGetVersion: name = "GET_VERSION"; break;
    case Command::kInputSource: name = "SOURCE_SEL"; break;
    case Command::kHardwareStatus: name = "STATUS_HW"; break;
    case Command::kSystemStatus: name = "STATUS_SYS"; break;
    case Command::kMainStatus: name = "STATUS_MAIN"; break;
    case Command::kLutValidate: name = "LUT_VALID"; break;
    case Command::kDisplayMode: name = "DISP_MODE"; break;
    case Command::kTrigOut1: name = "TRIG_OUT1_CTL"; break;
    case Command::kTrigOut2: name = "TRIG_OUT2_CTL"; break;
    case Command::kPatternSource: name = "PAT_DISP_MODE"; break;
    case Command::kPatternTriggerMode: name = "PAT_TRIG_MODE"; break;
    case Command::kPatternStartStop: name = "PAT_START_STOP"; break;
    case Command::kExposureFramePeriod: name = "PAT_EXPO_PRD"; break;
    case Command::kPatternConfig: name = "PAT_CONFIG"; break;
    case Command::kMailboxAddress: name = "MBOX_ADDRESS"; break;
    case Command::kMailboxControl: name = "MBOX_CONTROL"; break;
    case Command::kMailboxData: name = "MBOX_DATA"; break;
    case Command::kNumImagesInFlash: name = "NUM_IMAGE_IN_FLASH"; break;
  }
  if (name == nullptr) return fmt::format("0x{:04X}", command);
  return fmt::format("{} (0x{:04X})", name, command);
}

std::vector<Report> encode_request(const Request& request) {
  std::vector<std::uint8_t> text;
  text.reserve(2 + request.data.size());
  ByteWriter out(text);
  out.u16(request.command);  // CMD3 first, then CMD2
  out.bytes(request.data.data(), request.data.size());
  if (text.size() > kMaxMessageSize) {
    throw_error(ErrorCode::kInvalidArgument, "DLPC350 {}: {} data bytes exceed the controller's {}-byte buffer",
                command_name(request.command), request.data.size(), kMaxMessageSize - 2);
  }
  std::uint8_t flags = 0;
  if (request.read) flags |= kFlagRead | kFlagReply;
  if (request.reply_requested) flags |= kFlagReply;
  return split_into_reports(flags, request.sequence, text);
}

std::vector<Report> encode_reply(const Reply& reply) {
  if (reply.data.size() > kMaxMessageSize) {
    throw_error(ErrorCode::kInvalidArgument, "DLPC350 reply: {} data bytes exceed {}", reply.data.size(),
                kMaxMessageSize);
  }
  std::uint8_t flags = kFlagReply;
  if (reply.read) flags |= kFlagRead;
  if (reply.error) flags |= kFlagError;
  return split_into_reports(flags, reply.sequence, reply.data);
}

std::optional<Request> RequestAssembler::feed(const std::uint8_t* report, std::size_t size) {
  try {
    if (expected_ == 0) {
      std::uint8_t flags = 0;
      pending_ = Request{};
      expected_ = start_message(report, size, "request", &flags, &pending_.sequence, &text_);
      if ((flags & kFlagError) != 0) {
        throw_error(ErrorCode::kDevice, "DLPC350 request: the error bit is set (flags 0x{:02x})", flags);
      }
      pending_.read = (flags & kFlagRead) != 0;
      pending_.reply_requested = (flags & kFlagReply) != 0;
      if (text_.size() + expected_ < 2) {
        throw_error(ErrorCode::kDevice, "DLPC350 request: length {} cannot hold the 2 command bytes",
                    text_.size() + expected_);
      }
    } else {
      expected_ = continue_message(report, size, expected_, "request", &text_);
    }
  } catch (...) {
    reset();
    throw;
  }
  if (expected_ != 0) return std::nullopt;
  pending_.command = static_cast<std::uint16_t>(text_[0] | (text_[1] << 8));
  pending_.data.assign(text_.begin() + 2, text_.end());
  Request done = std::move(pending_);
  reset();
  return done;
}

void RequestAssembler::reset() {
  pending_ = Request{};
  text_.clear();
  expected_ = 0;
}

std::optional<Reply> ReplyAssembler::feed(const std::uint8_t* report, std::size_t size) {
  try {
    if (expected_ == 0) {
      std::uint8_t flags = 0;
      pending_ = Reply{};
      expected_ = start_message(report, size, "reply", &flags, &pending_.sequence, &pending_.data);
      if ((flags & kFlagReply) == 0) {
        throw_error(ErrorCode::kDevice, "DLPC350 reply: the reply bit is clear (flags 0x{:02x}): not a reply", flags);
      }
      pending_.read = (flags & kFlagRead) != 0;
      pending_.error = (flags & kFlagError) != 0;
    } else {
      expected_ = continue_message(report, size, expected_, "reply", &pending_.data);
    }
  } catch (...) {
    reset();
    throw;
  }
  if (expected_ != 0) return std::nullopt;
  Reply done = std::move(pending_);
  reset();
  return done;
}

void ReplyAssembler::reset() {
  pending_ = Reply{};
  expected_ = 0;
}

Reply decode_reply(const std::uint8_t* bytes, std::size_t size) {
  ReplyAssembler assembler;
  std::size_t offset = 0;
  do {
    const std::size_t count = std::min(kReportSize, size - offset);
    std::optional<Reply> reply = assembler.feed(bytes + offset, count);
    offset += count;
    if (reply) {
      if (offset != size) {
        throw_error(ErrorCode::kDevice, "DLPC350 reply: {} byte(s) follow the end of the reply", size - offset);
      }
      return *reply;
    }
  } while (offset < size);
  throw_error(ErrorCode::kDevice, "DLPC350 reply: truncated after {} byte(s): continuation reports missing", size);
}

// ---- typed payloads ---------------------------------------------------------------------

std::uint8_t trigger_delay_code(double delay_us) {
  const double code = std::round(delay_us / kTriggerDelayStepUs) + kTriggerDelayZero;
  return static_cast<std::uint8_t>(std::clamp(code, 0.0, static_cast<double>(0xD5)));
}

double trigger_delay_us(std::uint8_t code) { return (code - kTriggerDelayZero) * kTriggerDelayStepUs; }

std::vector<std::uint8_t> encode_trig_out1(const TriggerOutputConfig& config) {
  return {static_cast<std::uint8_t>(config.active_low ? 1 : 0), config.rising_delay, config.falling_delay};
}
std::vector<std::uint8_t> encode_trig_out2(const TriggerOutputConfig& config) {
  return {static_cast<std::uint8_t>(config.active_low ? 1 : 0), config.rising_delay};
}
TriggerOutputConfig decode_trig_out1(const std::vector<std::uint8_t>& data) {
  ByteReader in(data.data(), data.size(), "DLPC350 TRIG_OUT1_CTL");
  TriggerOutputConfig config;
  config.active_low = in.flag("invert");
  config.rising_delay = in.u8("rising delay");
  config.falling_delay = in.u8("falling delay");
  return config;
}
TriggerOutputConfig decode_trig_out2(const std::vector<std::uint8_t>& data) {
  ByteReader in(data.data(), data.size(), "DLPC350 TRIG_OUT2_CTL");
  TriggerOutputConfig config;
  config.active_low = in.flag("invert");
  config.rising_delay = in.u8("rising delay");
  config.falling_delay = kTriggerDelayZero;
  return config;
}

std::vector<std::uint8_t> encode_exposure(const ExposureTiming& timing) {
  std::vector<std::uint8_t> data;
  ByteWriter out(data);
  out.u32(timing.exposure_us);
  out.u32(timing.frame_period_us);
  return data;
}
ExposureTiming decode_exposure(const std::vector<std::uint8_t>& data) {
  ByteReader in(data.data(), data.size(), "DLPC350 PAT_EXPO_PRD");
  ExposureTiming timing;
  timing.exposure_us = in.u32("exposure");
  timing.frame_period_us = in.u32("frame period");
  return timing;
}

std::vector<std::uint8_t> encode_pattern_config(const PatternConfig& config) {
  if (config.lut_entries < 1 || config.lut_entries > kMaxLutEntries || config.patterns_per_trig_out2 < 1 ||
      config.patterns_per_trig_out2 > 256 || config.image_count < 1 || config.image_count > kMaxImageLutEntries) {
    throw_error(ErrorCode::kInvalidArgument,
                "DLPC350 PAT_CONFIG: {} LUT entries (1..{}), {} patterns per TRIG_OUT2 (1..256), {} images (1..{})",
                config.lut_entries, kMaxLutEntries, config.patterns_per_trig_out2, config.image_count,
                kMaxImageLutEntries);
  }
  // The controller takes counts minus one (0 means 1).
  return {static_cast<std::uint8_t>(config.lut_entries - 1), static_cast<std::uint8_t>(config.repeat ? 1 : 0),
          static_cast<std::uint8_t>(config.patterns_per_trig_out2 - 1), static_cast<std::uint8_t>(config.image_count - 1)};
}
PatternConfig decode_pattern_config(const std::vector<std::uint8_t>& data) {
  ByteReader in(data.data(), data.size(), "DLPC350 PAT_CONFIG");
  PatternConfig config;
  config.lut_entries = in.u8("LUT entries") + 1;
  config.repeat = in.flag("repeat");
  config.patterns_per_trig_out2 = in.u8("patterns per TRIG_OUT2") + 1;
  config.image_count = in.u8("image count") + 1;
  if (config.lut_entries > kMaxLutEntries || config.image_count > kMaxImageLutEntries) {
    throw_error(ErrorCode::kDevice, "DLPC350 PAT_CONFIG: {} LUT entries (max {}), {} images (max {})",
                config.lut_entries, kMaxLutEntries, config.image_count, kMaxImageLutEntries);
  }
  return config;
}

std::array<std::uint8_t, kLutEntrySize> encode_lut_entry(const LutEntry& entry) {
  if (static_cast<unsigned>(entry.trigger) > 3 || entry.pattern_number > 63 || entry.bit_depth < 1 ||
      entry.bit_depth > 8 || entry.leds > 7) {
    throw_error(ErrorCode::kInvalidArgument,
                "DLPC350 LUT entry: trigger {}, pattern {} (0..63), bit depth {} (1..8), LEDs {} (0..7)",
                static_cast<unsigned>(entry.trigger), entry.pattern_number, entry.bit_depth, entry.leds);
  }
  std::uint32_t word = static_cast<std::uint32_t>(entry.trigger) | (std::uint32_t{entry.pattern_number} << 2) |
                       (std::uint32_t{entry.bit_depth} << 8) | (std::uint32_t{entry.leds} << 12);
  if (entry.invert) word |= 1u << 16;
  if (entry.insert_black) word |= 1u << 17;
  if (entry.buffer_swap) word |= 1u << 18;
  if (entry.trigger_out_previous) word |= 1u << 19;
  return {static_cast<std::uint8_t>(word & 0xFF), static_cast<std::uint8_t>((word >> 8) & 0xFF),
          static_cast<std::uint8_t>((word >> 16) & 0xFF)};
}

LutEntry decode_lut_entry(const std::uint8_t* bytes) {
  const std::uint32_t word = bytes[0] | (std::uint32_t{bytes[1]} << 8) | (std::uint32_t{bytes[2]} << 16);
  constexpr std::uint32_t kReserved = (1u << 15) | (0xFu << 20);
  if ((word & kReserved) != 0) {
    throw_error(ErrorCode::kDevice, "DLPC350 LUT entry 0x{:06x}: reserved bits set", word);
  }
  LutEntry entry;
  entry.trigger = static_cast<LutTrigger>(word & 3u);
  entry.pattern_number = static_cast<std::uint8_t>((word >> 2) & 0x3Fu);
  entry.bit_depth = static_cast<std::uint8_t>((word >> 8) & 0xFu);
  entry.leds = static_cast<std::uint8_t>((word >> 12) & 0x7u);
  entry.invert = (word & (1u << 16)) != 0;
  entry.insert_black = (word & (1u << 17)) != 0;
  entry.buffer_swap = (word & (1u << 18)) != 0;
  entry.trigger_out_previous = (word & (1u << 19)) != 0;
  return entry;
}

std::vector<std::uint8_t> encode_lut_entries(const std::vector<LutEntry>& entries) {
  std::vector<std::uint8_t> data;
  data.reserve(entries.size() * kLutEntrySize);
  for (const LutEntry& entry : entries) {
    const auto bytes = encode_lut_entry(entry);
    data.insert(data.end(), bytes.begin(), bytes.end());
  }
  return data;
}

std::vector<LutEntry> decode_lut_entries(const std::vector<std::uint8_t>& data) {
  if (data.size() % kLutEntrySize != 0) {
    throw_error(ErrorCode::kDevice, "DLPC350 pattern LUT: {} bytes is not a whole number of 3-byte entries",
                data.size());
  }
  std::vector<LutEntry> entries;
  for (std::size_t offset = 0; offset < data.size(); offset += kLutEntrySize) {
    entries.push_back(decode_lut_entry(data.data() + offset));
  }
  return entries;
}

std::vector<std::uint8_t> encode_image_lut(const std::vector<std::uint8_t>& flash_images) {
  std::vector<std::uint8_t> data = flash_images;
  if (data.size() == 2) std::swap(data[0], data[1]);
  return data;
}

std::vector<std::uint8_t> decode_image_lut(const std::vector<std::uint8_t>& data) {
  return encode_image_lut(data);  // the swap is its own inverse
}

std::string ValidationStatus::describe() const {
  std::string text;
  auto add = [&text](const char* what) {
    if (!text.empty()) text += "; ";
    text += what;
  };
  if ((bits & kExposureInvalid) != 0) add("exposure or frame period invalid");
  if ((bits & kPatternNumbersInvalid) != 0) add("pattern numbers in the LUT invalid");
  if ((bits & kTrigOut1Overlap) != 0) add("warning: continuous TRIG_OUT1 request or overlapping black sectors");
  if ((bits & kPostVectorMissing) != 0) add("warning: no post vector before an externally triggered pattern");
  if ((bits & kPeriodTooClose) != 0) add("warning: frame period and exposure differ by less than 230 us");
  if ((bits & kBusy) != 0) add("validation in progress");
  return text.empty() ? "valid" : text;
}

std::string HardwareStatus::describe() const {
  std::string text = initialized() ? "initialized" : "initialization error";
  if (drc_error()) text += "; DMD reset waveform (DRC) error";
  if (forced_swap_error()) text += "; forced buffer swap error";
  if (sequence_abort()) text += "; sequence abort";
  if (sequence_error()) text += "; sequence error";
  return text;
}

std::string Version::format(std::uint32_t word) {
  return fmt::format("{}.{}.{}", word >> 24, (word >> 16) & 0xFFu, word & 0xFFFFu);
}

std::vector<std::uint8_t> encode_version(const Version& version) {
  std::vector<std::uint8_t> data;
  ByteWriter out(data);
  out.u32(version.application);
  out.u32(version.api);
  out.u32(version.software_config);
  out.u32(version.sequence_config);
  return data;
}

Version decode_version(const std::vector<std::uint8_t>& data) {
  ByteReader in(data.data(), data.size(), "DLPC350 GET_VERSION");
  Version version;
  version.application = in.u32("application version");
  version.api = in.u32("API version");
  version.software_config = in.u32("software configuration version");
  version.sequence_config = in.u32("sequence configuration version");
  return version;
}

std::uint8_t decode_byte(const std::vector<std::uint8_t>& data, Command command) {
  if (data.empty()) throw_error(ErrorCode::kDevice, "DLPC350 {}: the reply carries no data", command_name(command));
  return data[0];
}

}  // namespace sls::fwif::dlpc350
