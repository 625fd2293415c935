#include "drivers/dlpc350/dlpc350_projector.h"

#include <fmt/format.h>

#include <thread>

#include "sdk/core/error.h"

namespace sls::drivers {

using namespace fwif::dlpc350;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

namespace {

constexpr int kPatternsPerImage = 3;  // 8-bit patterns: the G, R and B planes of a 24-bit image
constexpr milliseconds kPollInterval{1};

milliseconds remaining_until(Clock::time_point deadline) {
  return std::max(milliseconds{1}, std::chrono::duration_cast<milliseconds>(deadline - Clock::now()));
}

}  // namespace

Dlpc350FlashSlot dlpc350_flash_slot(int index, int first_flash_image) {
  return {first_flash_image + index / kPatternsPerImage, index % kPatternsPerImage};
}

int dlpc350_pattern_index(const Dlpc350FlashSlot& slot, int first_flash_image) {
  if (slot.flash_image < first_flash_image || slot.pattern_number < 0 || slot.pattern_number >= kPatternsPerImage) {
    return -1;
  }
  return (slot.flash_image - first_flash_image) * kPatternsPerImage + slot.pattern_number;
}

std::vector<std::array<int, 3>> dlpc350_flash_layout(const PatternSet& set) {
  std::vector<std::array<int, 3>> images((set.size() + kPatternsPerImage - 1) / kPatternsPerImage, {-1, -1, -1});
  for (std::size_t i = 0; i < set.size(); ++i) images[i / kPatternsPerImage][i % kPatternsPerImage] = static_cast<int>(i);
  return images;
}

Dlpc350Projector::Dlpc350Projector(std::unique_ptr<usb::UsbConnection> connection, Dlpc350Options options,
                                   std::string uri)
    : connection_(std::move(connection)), options_(std::move(options)), uri_(std::move(uri)) {}

Dlpc350Projector::~Dlpc350Projector() = default;

std::unique_ptr<Dlpc350Projector> Dlpc350Projector::open(const usb::UsbSelector& selector, Dlpc350Options options) {
  auto connection = usb::UsbConnection::open(selector, kInterfaceNumber, "DLPC350");
  const std::string uri = fmt::format("dlpc350://{}:{}", connection->info().bus, connection->info().address);
  std::unique_ptr<Dlpc350Projector> projector(new Dlpc350Projector(std::move(connection), std::move(options), uri));
  const Version v = projector->version();
  projector->firmware_ = fmt::format("application {}, API {}", Version::format(v.application), Version::format(v.api));
  const Status status = projector->status();
  if (!status.hardware.initialized() || status.hardware.sequence_error() || status.hardware.drc_error()) {
    throw_error(ErrorCode::kDevice, "{}: hardware status 0x{:02x}: {}", projector->name(), status.hardware.bits,
                status.hardware.describe());
  }
  if (projector->power() == PowerMode::kStandby) projector->set_power(PowerMode::kNormal);
  return projector;
}

std::unique_ptr<Dlpc350Projector> Dlpc350Projector::open(const std::string& uri, Dlpc350Options options) {
  const DeviceUri parsed = parse_device_uri(uri);
  if (parsed.scheme != "dlpc350") {
    throw_error(ErrorCode::kInvalidArgument, "{} is not a dlpc350:// URI", uri);
  }
  return open(usb::usb_selector_from_uri(parsed, kVendorId, kProductId), std::move(options));
}

const std::string& Dlpc350Projector::name() const { return connection_->name(); }

ProjectorInfo Dlpc350Projector::info() const {
  return {uri_, "DLPC350 (TI LightCrafter 4500)", firmware_, kDmdWidth, kDmdHeight};
}

std::vector<std::uint8_t> Dlpc350Projector::transact(Command command, bool read, const std::vector<std::uint8_t>& data,
                                                      int attempts) {
  const milliseconds attempt_timeout = options_.retry.attempt_timeout();
  ErrorCode failure = ErrorCode::kTimeout;
  std::string problem;
  // Records a failed transfer; true means "give up this attempt".
  auto failed = [&](const usb::TransferResult& result, std::uint8_t endpoint) {
    return connection_->transfer_failed(result, endpoint, attempt_timeout, command_name(command), &failure, &problem);
  };

  for (int attempt = 0; attempt < attempts; ++attempt) {
    const std::uint8_t sequence = next_sequence_++;
    const Clock::time_point deadline = Clock::now() + attempt_timeout;
    bool give_up = false;
    for (const Report& report : encode_request(Request{read, true, sequence, static_cast<std::uint16_t>(command), data})) {
      if (failed(connection_->write(kEndpointOut, report.data(), report.size(), remaining_until(deadline)), kEndpointOut)) {
        give_up = true;
        break;
      }
    }
    ReplyAssembler assembler;
    while (!give_up) {
      Report buffer{};
      const usb::TransferResult result =
          connection_->read(kEndpointIn, buffer.data(), buffer.size(), remaining_until(deadline));
      if (failed(result, kEndpointIn)) break;
      std::optional<Reply> reply;
      try {
        reply = assembler.feed(buffer.data(), result.transferred);
      } catch (const Error& error) {
        failure = ErrorCode::kDevice;
        problem = fmt::format("malformed reply: {}", error.what());
        break;
      }
      if (!reply) continue;  // more reports of this reply to come
      if (reply->sequence != sequence) {  // a late reply to an attempt already given up
        if (Clock::now() < deadline) continue;
        failure = ErrorCode::kTimeout;
        problem = fmt::format("only replies to earlier requests arrived within {} ms", attempt_timeout.count());
        break;
      }
      if (reply->error) {
        throw_error(ErrorCode::kDevice, "{}: the controller refused {} {} (error bit in its reply)", name(),
                    read ? "read" : "write", command_name(command));
      }
      if (reply->read != read) {
        failure = ErrorCode::kDevice;
        problem = fmt::format("the reply is to a {}, not a {}", reply->read ? "read" : "write", read ? "read" : "write");
        break;
      }
      return std::move(reply->data);
    }
  }
  throw_error(failure, "{}: {} {}: {} ({} attempt(s), {} ms in all)", name(), read ? "read" : "write",
              command_name(command), problem, attempts, attempts * attempt_timeout.count());
}

std::vector<std::uint8_t> Dlpc350Projector::read(Command command) {
  return transact(command, true, {}, options_.retry.attempts);
}

void Dlpc350Projector::write(Command command, const std::vector<std::uint8_t>& data) {
  transact(command, false, data, options_.retry.attempts);
}

Version Dlpc350Projector::version() { return decode_version(read(Command::kGetVersion)); }

Dlpc350Projector::Status Dlpc350Projector::status() {
  Status status;
  status.hardware.bits = decode_byte(read(Command::kHardwareStatus), Command::kHardwareStatus);
  status.system.bits = decode_byte(read(Command::kSystemStatus), Command::kSystemStatus);
  status.main.bits = decode_byte(read(Command::kMainStatus), Command::kMainStatus);
  return status;
}

PowerMode Dlpc350Projector::power() {
  // Bits 1:0 report the state; any of them set means standby (TI's reference host code).
  return (decode_byte(read(Command::kPowerControl), Command::kPowerControl) & 0x03) != 0 ? PowerMode::kStandby
                                                                                          : PowerMode::kNormal;
}

void Dlpc350Projector::set_power(PowerMode mode) {
  write(Command::kPowerControl, {static_cast<std::uint8_t>(mode)});
  if (mode == PowerMode::kStandby) {
    shown_ = -1;
    playing_since_.reset();
  }
}

void Dlpc350Projector::set_display_mode(DisplayMode mode) {
  write(Command::kDisplayMode, {static_cast<std::uint8_t>(mode)});
}

void Dlpc350Projector::set_pattern_source(PatternSource source) {
  write(Command::kPatternSource, {static_cast<std::uint8_t>(source)});
}

void Dlpc350Projector::set_trigger_mode(TriggerMode mode) {
  write(Command::kPatternTriggerMode, {static_cast<std::uint8_t>(mode)});
}

void Dlpc350Projector::configure_trigger_output(int output, const TriggerOutputConfig& config) {
  if (output == 1) write(Command::kTrigOut1, encode_trig_out1(config));
  else if (output == 2) write(Command::kTrigOut2, encode_trig_out2(config));
  else throw_error(ErrorCode::kInvalidArgument, "{}: there is no TRIG_OUT{} (1 or 2)", name(), output);
}

void Dlpc350Projector::set_exposure(const ExposureTiming& timing) {
  write(Command::kExposureFramePeriod, encode_exposure(timing));
}

ExposureTiming Dlpc350Projector::exposure() { return decode_exposure(read(Command::kExposureFramePeriod)); }

void Dlpc350Projector::write_mailbox(Mailbox mailbox, const std::vector<std::uint8_t>& data) {
  write(Command::kMailboxControl, {static_cast<std::uint8_t>(mailbox)});
  // MBOX_DATA advances the mailbox address, so a retried data write would land after the
  // first one: retry the address and the data together instead.
  for (int attempt = 1;; ++attempt) {
    try {
      write(Command::kMailboxAddress, {0});
      transact(Command::kMailboxData, false, data, 1);
      break;
    } catch (const Error& error) {
      if (error.code() != ErrorCode::kTimeout || attempt >= options_.retry.attempts) throw;
    }
  }
  write(Command::kMailboxControl, {static_cast<std::uint8_t>(Mailbox::kClosed)});
}

void Dlpc350Projector::write_luts(const PatternConfig& config, const std::vector<LutEntry>& entries,
                                  const std::vector<std::uint8_t>& flash_images) {
  if (static_cast<int>(entries.size()) != config.lut_entries ||
      static_cast<int>(flash_images.size()) != config.image_count) {
    throw_error(ErrorCode::kInvalidArgument, "{}: PAT_CONFIG says {} entries and {} images, given {} and {}", name(),
                config.lut_entries, config.image_count, entries.size(), flash_images.size());
  }
  write(Command::kPatternConfig, encode_pattern_config(config));
  write_mailbox(Mailbox::kPatternLut, encode_lut_entries(entries));
  write_mailbox(Mailbox::kImageLut, encode_image_lut(flash_images));
}

std::vector<LutEntry> Dlpc350Projector::read_pattern_lut(int entries) {
  write(Command::kMailboxControl, {static_cast<std::uint8_t>(Mailbox::kPatternLut)});
  write(Command::kMailboxAddress, {0});
  std::vector<LutEntry> lut = decode_lut_entries(read(Command::kMailboxData));
  write(Command::kMailboxControl, {static_cast<std::uint8_t>(Mailbox::kClosed)});
  if (static_cast<int>(lut.size()) < entries) {
    throw_error(ErrorCode::kDevice, "{}: the pattern LUT read back has {} entries, {} expected", name(), lut.size(),
                entries);
  }
  lut.resize(static_cast<std::size_t>(entries));
  return lut;
}

ValidationStatus Dlpc350Projector::validate() {
  write(Command::kLutValidate, {0});
  const Clock::time_point deadline = Clock::now() + options_.settle_timeout;
  ValidationStatus status;
  for (;;) {
    status.bits = decode_byte(read(Command::kLutValidate), Command::kLutValidate);
    if (!status.busy()) break;
    if (Clock::now() >= deadline) {
      throw_error(ErrorCode::kTimeout, "{}: LUT validation still busy after {} ms", name(),
                  options_.settle_timeout.count());
    }
    std::this_thread::sleep_for(kPollInterval);
  }
  if (!status.valid()) {
    throw_error(ErrorCode::kDevice, "{}: the controller rejected the pattern sequence (validation 0x{:02x}: {})",
                name(), status.bits, status.describe());
  }
  return status;
}

void Dlpc350Projector::sequence(SequenceAction action) {
  write(Command::kPatternStartStop, {static_cast<std::uint8_t>(action)});
}

int Dlpc350Projector::flash_image_count() {
  return decode_byte(read(Command::kNumImagesInFlash), Command::kNumImagesInFlash);
}

void Dlpc350Projector::wait_until_running() {
  const Clock::time_point deadline = Clock::now() + options_.settle_timeout;
  while (!status().main.sequence_running()) {
    if (Clock::now() >= deadline) {
      throw_error(ErrorCode::kTimeout, "{}: the sequencer did not start within {} ms", name(),
                  options_.settle_timeout.count());
    }
    std::this_thread::sleep_for(kPollInterval);
  }
}

void Dlpc350Projector::prepare_pattern_mode() {
  sequence(SequenceAction::kStop);
  playing_since_.reset();
  shown_ = -1;
  set_display_mode(DisplayMode::kPattern);
  set_pattern_source(PatternSource::kFlash);
  set_trigger_mode(TriggerMode::kInternalOrExternal);
  configure_trigger_output(1, options_.trig_out1);
  configure_trigger_output(2, options_.trig_out2);
  set_exposure(options_.timing);
}

void Dlpc350Projector::load_full_sequence() {
  const int count = static_cast<int>(patterns_.size());
  std::vector<LutEntry> entries;
  std::vector<std::uint8_t> images;
  for (int i = 0; i < count; ++i) {
    const Dlpc350FlashSlot slot = dlpc350_flash_slot(i, options_.first_flash_image);
    LutEntry entry;
    entry.trigger = LutTrigger::kInternal;
    entry.pattern_number = static_cast<std::uint8_t>(slot.pattern_number);
    entry.bit_depth = 8;
    entry.leds = options_.leds;
    entry.buffer_swap = slot.pattern_number == 0;  // each new flash image starts with a buffer swap
    entries.push_back(entry);
    if (slot.pattern_number == 0) images.push_back(static_cast<std::uint8_t>(slot.flash_image));
  }
  PatternConfig config;
  config.lut_entries = count;
  config.repeat = false;
  config.patterns_per_trig_out2 = count;  // TRIG_OUT2 marks the start of each sequence
  config.image_count = static_cast<int>(images.size());
  write_luts(config, entries, images);
  lut_holds_sequence_ = false;
  validate();
  lut_holds_sequence_ = true;
}

void Dlpc350Projector::load_patterns(const PatternSet& patterns) {
  validate_pattern_set(patterns);
  if (patterns.projector_width != kDmdWidth || patterns.projector_height != kDmdHeight) {
    throw_error(ErrorCode::kInvalidArgument, "{}: pattern set '{}' is {} x {}; the DLP4500 shows {} x {} patterns",
                name(), patterns.name, patterns.projector_width, patterns.projector_height, kDmdWidth, kDmdHeight);
  }
  const int count = static_cast<int>(patterns.size());
  const int images = (count + kPatternsPerImage - 1) / kPatternsPerImage;
  if (count < 1 || count > kMaxLutEntries || images > kMaxImageLutEntries) {
    throw_error(ErrorCode::kInvalidArgument, "{}: pattern set '{}' has {} patterns; the LUT holds 1 to {}", name(),
                patterns.name, count, kMaxLutEntries);
  }
  const int in_flash = flash_image_count();
  if (options_.first_flash_image < 0 || options_.first_flash_image + images > in_flash) {
    throw_error(ErrorCode::kInvalidArgument,
                "{}: pattern set '{}' needs flash images {} to {}; the controller's flash holds {} image(s)", name(),
                patterns.name, options_.first_flash_image, options_.first_flash_image + images - 1, in_flash);
  }
  prepare_pattern_mode();
  patterns_ = patterns;
  try {
    load_full_sequence();
  } catch (...) {
    patterns_ = PatternSet{};  // nothing usable is loaded
    throw;
  }
}

const PatternSet& Dlpc350Projector::patterns() const { return patterns_; }

void Dlpc350Projector::show_pattern(int index) {
  if (index < 0 || static_cast<std::size_t>(index) >= patterns_.size()) {
    throw_error(ErrorCode::kInvalidArgument, "{}: pattern {} of a loaded set of {}", name(), index, patterns_.size());
  }
  sequence(SequenceAction::kStop);
  playing_since_.reset();
  shown_ = -1;
  const Dlpc350FlashSlot slot = dlpc350_flash_slot(index, options_.first_flash_image);
  LutEntry entry;
  entry.trigger = LutTrigger::kInternal;
  entry.pattern_number = static_cast<std::uint8_t>(slot.pattern_number);
  entry.bit_depth = 8;
  entry.leds = options_.leds;
  entry.buffer_swap = true;
  PatternConfig config;  // one entry, repeated: the pattern stays on, TRIG_OUT1 pulses each period
  config.lut_entries = 1;
  config.repeat = true;
  config.patterns_per_trig_out2 = 1;
  config.image_count = 1;
  lut_holds_sequence_ = false;
  write_luts(config, {entry}, {static_cast<std::uint8_t>(slot.flash_image)});
  validate();
  sequence(SequenceAction::kStart);
  wait_until_running();
  shown_ = index;
}

int Dlpc350Projector::current_pattern() const {
  if (playing_since_) {
    const auto elapsed = std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - *playing_since_);
    const std::int64_t frame = elapsed.count() / std::max<std::int64_t>(1, options_.timing.frame_period_us);
    return frame < static_cast<std::int64_t>(patterns_.size()) ? static_cast<int>(frame) : -1;
  }
  return shown_;
}

void Dlpc350Projector::go_dark() {
  sequence(SequenceAction::kStop);
  playing_since_.reset();
  shown_ = -1;
}

void Dlpc350Projector::play_sequence() {
  if (patterns_.size() == 0) throw_error(ErrorCode::kInvalidArgument, "{}: no pattern set loaded", name());
  sequence(SequenceAction::kStop);
  playing_since_.reset();
  shown_ = -1;
  if (!lut_holds_sequence_) load_full_sequence();
  sequence(SequenceAction::kStart);
  playing_since_ = Clock::now();
}

}  // namespace sls::drivers
