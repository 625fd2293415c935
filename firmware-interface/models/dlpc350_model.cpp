#include "firmware-interface/models/dlpc350_model.h"

#include <algorithm>

#include "sdk/core/error.h"

namespace sls::fwif::models {

using namespace dlpc350;

namespace {

// Shortest exposure per bit depth, from the LightCrafter 4500 user's guide (DLPU011) table of
// pattern rates: the DMD needs this long to show all bit planes of a pattern.
std::uint32_t minimum_exposure_us(int bit_depth) {
  static constexpr std::uint32_t kTable[9] = {0, 235, 700, 1570, 1700, 2000, 2500, 4500, 8333};
  return bit_depth >= 1 && bit_depth <= 8 ? kTable[bit_depth] : 0;
}

// Highest pattern number (bit-plane group of a 24-bit image) for a bit depth; for 1-bit
// patterns number 24 is TI's white/black fill pattern.
int maximum_pattern_number(int bit_depth) { return bit_depth == 1 ? 24 : 24 / bit_depth - 1; }

bool is_sequence_setting(std::uint16_t command) {
  switch (static_cast<Command>(command)) {
    case Command::kDisplayMode:
    case Command::kPatternSource:
    case Command::kPatternTriggerMode:
    case Command::kTrigOut1:
    case Command::kTrigOut2:
    case Command::kExposureFramePeriod:
    case Command::kPatternConfig:
    case Command::kMailboxAddress:
    case Command::kMailboxControl:
    case Command::kMailboxData:
    case Command::kLutValidate:
      return true;
    default:
      return false;
  }
}

}  // namespace

Dlpc350Model::Dlpc350Model(Dlpc350ModelOptions options, DeviceClock clock)
    : options_(std::move(options)), clock_(std::move(clock)) {
  state_.pattern_lut.assign(kMaxLutEntries, LutEntry{});
  state_.image_lut.assign(kMaxImageLutEntries, 0);
}

UsbIdentity Dlpc350Model::identity() const {
  UsbIdentity id;
  id.vendor_id = kVendorId;
  id.product_id = kProductId;
  id.manufacturer = "Texas Instruments";
  id.product = "DLPC350";
  id.serial = options_.serial;
  id.interface_class = 0x03;  // HID
  id.endpoints = {{kEndpointIn, EndpointType::kInterrupt, 64, 1}, {kEndpointOut, EndpointType::kInterrupt, 64, 1}};
  return id;
}

Dlpc350Model::State Dlpc350Model::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  State state = state_;
  if (sequence_finished()) state.sequence = SequenceAction::kStop;
  return state;
}

std::optional<DisplayedPattern> Dlpc350Model::displayed_pattern() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return displayed_locked();
}

std::uint64_t Dlpc350Model::trigger_out1_pulses() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pulses_locked();
}

std::uint64_t Dlpc350Model::pulses_locked() const {
  std::uint64_t pulses = pulses_before_run_;
  if (state_.sequence == SequenceAction::kStart) {
    const std::int64_t period = std::max<std::int64_t>(1, state_.exposure.frame_period_us);
    std::int64_t shown = (clock_() - started_at_us_) / period + 1;
    if (!state_.pattern_config.repeat) {
      shown = std::min<std::int64_t>(shown, state_.pattern_config.lut_entries - frames_before_start_);
    }
    pulses += static_cast<std::uint64_t>(std::max<std::int64_t>(0, shown));
  }
  return pulses;
}

std::vector<Request> Dlpc350Model::requests() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return requests_;
}

std::vector<Report> Dlpc350Model::reports() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return reports_;
}

void Dlpc350Model::clear_requests() {
  std::lock_guard<std::mutex> lock(mutex_);
  requests_.clear();
  reports_.clear();
}

void Dlpc350Model::refuse(Command command) {
  std::lock_guard<std::mutex> lock(mutex_);
  refused_.insert(static_cast<std::uint16_t>(command));
}

TransferOutcome Dlpc350Model::handle_write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size) {
  if (endpoint != kEndpointOut) return TransferOutcome::kStall;
  std::lock_guard<std::mutex> lock(mutex_);
  Report raw{};
  std::copy(data, data + std::min(size, raw.size()), raw.begin());
  reports_.push_back(raw);
  std::optional<Request> request;
  try {
    request = assembler_.feed(data, size);
  } catch (const Error&) {
    // A request the firmware cannot parse: NACK it when the host asked for a reply.
    if (size >= 2 && (data[0] & kFlagReply) != 0) {
      queue_reply(Reply{(data[0] & kFlagRead) != 0, true, data[1], {}});
    }
    return TransferOutcome::kDone;
  }
  if (request) execute(*request);
  return TransferOutcome::kDone;
}

TransferOutcome Dlpc350Model::handle_read(std::uint8_t endpoint, std::size_t capacity, std::vector<std::uint8_t>& out) {
  if (endpoint != kEndpointIn) return TransferOutcome::kStall;
  std::lock_guard<std::mutex> lock(mutex_);
  if (replies_.empty()) return TransferOutcome::kPending;
  const Report& report = replies_.front();
  out.assign(report.begin(), report.begin() + static_cast<std::ptrdiff_t>(std::min(capacity, report.size())));
  replies_.pop_front();
  return TransferOutcome::kDone;
}

void Dlpc350Model::queue_reply(const Reply& reply) {
  for (const Report& report : encode_reply(reply)) replies_.push_back(report);
}

void Dlpc350Model::execute(const Request& request) {
  requests_.push_back(request);
  if (sequence_finished()) stop_sequence();  // a non-repeating sequence stops by itself
  Reply reply;
  reply.read = request.read;
  reply.sequence = request.sequence;
  if (refused_.count(request.command) != 0) {
    reply.error = true;
  } else if (request.read) {
    std::optional<std::vector<std::uint8_t>> data = execute_read(request.command);
    reply.error = !data.has_value();
    if (data) reply.data = std::move(*data);
  } else {
    reply.error = !execute_write(request.command, request.data);
  }
  if (request.read || request.reply_requested) queue_reply(reply);
}

std::optional<std::vector<std::uint8_t>> Dlpc350Model::execute_read(std::uint16_t command) {
  auto byte = [](auto value) { return std::vector<std::uint8_t>{static_cast<std::uint8_t>(value)}; };
  switch (static_cast<Command>(command)) {
    case Command::kPowerControl: return byte(state_.power);
    case Command::kGetVersion: return encode_version(options_.version);
    case Command::kHardwareStatus: return byte(0x01);  // initialized, no errors
    case Command::kSystemStatus: return byte(0x01);    // memory test passed
    case Command::kMainStatus: {
      std::uint8_t bits = 0;
      if (state_.power == PowerMode::kStandby) bits |= 0x01;           // DMD parked
      if (state_.sequence == SequenceAction::kStart) bits |= 0x02;     // sequencer running
      return byte(bits);
    }
    case Command::kLutValidate:
      if (validation_busy_left_ > 0) {
        --validation_busy_left_;
        return byte(validation_bits_ | ValidationStatus::kBusy);
      }
      return byte(validation_bits_);
    case Command::kDisplayMode: return byte(state_.display_mode);
    case Command::kTrigOut1: return encode_trig_out1(state_.trig_out1);
    case Command::kTrigOut2: return encode_trig_out2(state_.trig_out2);
    case Command::kPatternSource: return byte(state_.pattern_source);
    case Command::kPatternTriggerMode: return byte(state_.trigger_mode);
    case Command::kPatternStartStop: return byte(state_.sequence);
    case Command::kExposureFramePeriod: return encode_exposure(state_.exposure);
    case Command::kPatternConfig: return encode_pattern_config(state_.pattern_config);
    case Command::kMailboxAddress: return byte(state_.mailbox_address);
    case Command::kMailboxControl: return byte(state_.mailbox);
    case Command::kMailboxData: {
      const auto from = static_cast<std::size_t>(state_.mailbox_address);
      if (state_.mailbox == Mailbox::kPatternLut) {
        const auto to = std::max(from, static_cast<std::size_t>(state_.pattern_config.lut_entries));
        return encode_lut_entries({state_.pattern_lut.begin() + static_cast<std::ptrdiff_t>(from),
                                   state_.pattern_lut.begin() + static_cast<std::ptrdiff_t>(to)});
      }
      if (state_.mailbox == Mailbox::kImageLut) {
        const auto to = std::max(from, static_cast<std::size_t>(state_.pattern_config.image_count));
        return encode_image_lut({state_.image_lut.begin() + static_cast<std::ptrdiff_t>(from),
                                 state_.image_lut.begin() + static_cast<std::ptrdiff_t>(to)});
      }
      return std::nullopt;
    }
    case Command::kNumImagesInFlash: return byte(options_.flash_images);
    case Command::kInputSource: return byte(0);
  }
  return std::nullopt;
}

bool Dlpc350Model::execute_write(std::uint16_t command, const std::vector<std::uint8_t>& data) {
  if (data.empty()) return false;
  const std::uint8_t value = data[0];
  const auto which = static_cast<Command>(command);
  if (state_.power == PowerMode::kStandby && which != Command::kPowerControl) return false;
  if (is_sequence_setting(command)) {
    // The guide: stop the sequence before changing it, validate before starting again.
    if (state_.sequence != SequenceAction::kStop) return false;
    if (which != Command::kLutValidate) state_.validated = false;
  }
  try {
    switch (which) {
      case Command::kPowerControl:
        if (value > 1) return false;
        if (value == 1) stop_sequence();
        state_.power = static_cast<PowerMode>(value);
        return true;
      case Command::kDisplayMode:
        if (value > 1) return false;
        state_.display_mode = static_cast<DisplayMode>(value);
        return true;
      case Command::kPatternSource:
        if (value != 0 && value != 3) return false;
        state_.pattern_source = static_cast<PatternSource>(value);
        return true;
      case Command::kPatternTriggerMode:
        if (value > 4) return false;
        state_.trigger_mode = static_cast<TriggerMode>(value);
        return true;
      case Command::kTrigOut1: state_.trig_out1 = decode_trig_out1(data); return true;
      case Command::kTrigOut2: state_.trig_out2 = decode_trig_out2(data); return true;
      case Command::kExposureFramePeriod: state_.exposure = decode_exposure(data); return true;
      case Command::kPatternConfig: state_.pattern_config = decode_pattern_config(data); return true;
      case Command::kMailboxControl:
        if (value > 3) return false;
        state_.mailbox = static_cast<Mailbox>(value);
        return true;
      case Command::kMailboxAddress:
        if (value >= kMaxLutEntries) return false;
        state_.mailbox_address = value;
        return true;
      case Command::kMailboxData: return write_mailbox(data);
      case Command::kLutValidate:
        validation_bits_ = validate();
        validation_busy_left_ = options_.validation_busy_reads;
        state_.validated = ValidationStatus{validation_bits_}.valid();
        return true;
      case Command::kPatternStartStop:
        if (value > 2) return false;
        if (value == 0) {
          stop_sequence();
        } else if (value == 1) {
          if (state_.sequence == SequenceAction::kStart) {
            pulses_before_run_ = pulses_locked();
            frames_before_start_ = frames_since_start();
            state_.sequence = SequenceAction::kPause;
          }
        } else if (state_.sequence != SequenceAction::kStart) {
          if (state_.display_mode != DisplayMode::kPattern || !state_.validated || validation_busy_left_ > 0) {
            return false;
          }
          started_at_us_ = clock_();
          state_.sequence = SequenceAction::kStart;
        }
        return true;
      case Command::kInputSource: return true;
      default: return false;
    }
  } catch (const Error&) {
    return false;  // a malformed payload (short, bad flag byte): the firmware NACKs it
  }
}

bool Dlpc350Model::write_mailbox(const std::vector<std::uint8_t>& data) {
  const auto at = static_cast<std::size_t>(state_.mailbox_address);
  if (state_.mailbox == Mailbox::kPatternLut) {
    const std::vector<LutEntry> entries = decode_lut_entries(data);
    if (at + entries.size() > state_.pattern_lut.size()) return false;
    std::copy(entries.begin(), entries.end(), state_.pattern_lut.begin() + static_cast<std::ptrdiff_t>(at));
    state_.mailbox_address = static_cast<int>(at + entries.size()) % kMaxLutEntries;
    return true;
  }
  if (state_.mailbox == Mailbox::kImageLut) {
    const std::vector<std::uint8_t> images = decode_image_lut(data);
    if (at + images.size() > state_.image_lut.size()) return false;
    std::copy(images.begin(), images.end(), state_.image_lut.begin() + static_cast<std::ptrdiff_t>(at));
    state_.mailbox_address = static_cast<int>(at + images.size()) % kMaxLutEntries;
    return true;
  }
  return false;  // closed, or the variable-exposure LUT this model does not emulate
}

std::uint8_t Dlpc350Model::validate() const {
  std::uint8_t bits = 0;
  const PatternConfig& config = state_.pattern_config;
  int deepest = 1;
  int image_swaps = 0;
  for (int i = 0; i < config.lut_entries; ++i) {
    const LutEntry& entry = state_.pattern_lut[static_cast<std::size_t>(i)];
    if (entry.bit_depth < 1 || entry.bit_depth > 8 || entry.pattern_number > maximum_pattern_number(entry.bit_depth)) {
      bits |= ValidationStatus::kPatternNumbersInvalid;
    } else {
      deepest = std::max<int>(deepest, entry.bit_depth);
    }
    if (i > 0 && entry.buffer_swap) ++image_swaps;
    if (i > 0 && (entry.trigger == LutTrigger::kExternalPositive || entry.trigger == LutTrigger::kExternalNegative) &&
        !state_.pattern_lut[static_cast<std::size_t>(i - 1)].insert_black) {
      bits |= ValidationStatus::kPostVectorMissing;
    }
  }
  if (state_.pattern_source == PatternSource::kFlash) {
    if (image_swaps + 1 > config.image_count) bits |= ValidationStatus::kPatternNumbersInvalid;
    for (int i = 0; i < config.image_count; ++i) {
      if (state_.image_lut[static_cast<std::size_t>(i)] >= options_.flash_images) {
        bits |= ValidationStatus::kPatternNumbersInvalid;
      }
    }
  }
  const ExposureTiming& timing = state_.exposure;
  if (timing.exposure_us == 0 || timing.exposure_us > timing.frame_period_us ||
      timing.exposure_us < minimum_exposure_us(deepest)) {
    bits |= ValidationStatus::kExposureInvalid;
  } else if (timing.frame_period_us != timing.exposure_us && timing.frame_period_us - timing.exposure_us < 230) {
    bits |= ValidationStatus::kPeriodTooClose;
  }
  return bits;
}

std::int64_t Dlpc350Model::frames_since_start() const {
  switch (state_.sequence) {
    case SequenceAction::kStop: return 0;
    case SequenceAction::kPause: return frames_before_start_;
    case SequenceAction::kStart: break;
  }
  const std::int64_t period = std::max<std::int64_t>(1, state_.exposure.frame_period_us);
  return frames_before_start_ + (clock_() - started_at_us_) / period;
}

bool Dlpc350Model::sequence_finished() const {
  return state_.sequence != SequenceAction::kStop && !state_.pattern_config.repeat &&
         frames_since_start() >= state_.pattern_config.lut_entries;
}

std::optional<DisplayedPattern> Dlpc350Model::displayed_locked() const {
  if (state_.power == PowerMode::kStandby || state_.display_mode != DisplayMode::kPattern ||
      state_.sequence == SequenceAction::kStop || sequence_finished()) {
    return std::nullopt;
  }
  const PatternConfig& config = state_.pattern_config;
  const auto index = static_cast<int>(frames_since_start() % config.lut_entries);
  int image_position = 0;
  for (int i = 1; i <= index; ++i) {
    if (state_.pattern_lut[static_cast<std::size_t>(i)].buffer_swap) ++image_position;
  }
  const LutEntry& entry = state_.pattern_lut[static_cast<std::size_t>(index)];
  DisplayedPattern shown;
  shown.lut_index = index;
  shown.flash_image = state_.image_lut[static_cast<std::size_t>(image_position % config.image_count)];
  shown.pattern_number = entry.pattern_number;
  shown.bit_depth = entry.bit_depth;
  shown.inverted = entry.invert;
  shown.leds = entry.leds;
  return shown;
}

void Dlpc350Model::stop_sequence() {
  pulses_before_run_ = pulses_locked();
  frames_before_start_ = 0;
  state_.sequence = SequenceAction::kStop;
}

}  // namespace sls::fwif::models
