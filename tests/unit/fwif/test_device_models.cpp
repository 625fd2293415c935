// The device models (emulated firmware) on their own, fed with bytes as the USB bus would,
// on a clock the test drives.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <memory>

#include "firmware-interface/dlpc350/dlpc350_codec.h"
#include "firmware-interface/headctl/headctl_codec.h"
#include "firmware-interface/models/dlpc350_model.h"
#include "firmware-interface/models/headctl_model.h"
#include "sdk/core/error.h"

namespace sls::fwif::models {
namespace {

struct ManualClock {
  std::shared_ptr<std::atomic<std::int64_t>> now = std::make_shared<std::atomic<std::int64_t>>(1'000'000);
  DeviceClock clock() const {
    auto time = now;
    return [time] { return time->load(); };
  }
  void advance_us(std::int64_t us) { *now += us; }
};

// ---- DLPC350 ------------------------------------------------------------------------------
class Dlpc350Host {
 public:
  explicit Dlpc350Host(Dlpc350Model& model) : model_(model) {}

  dlpc350::Reply send(bool read, dlpc350::Command command, std::vector<std::uint8_t> data = {}) {
    for (const dlpc350::Report& report :
         dlpc350::encode_request({read, true, sequence_++, static_cast<std::uint16_t>(command), std::move(data)})) {
      EXPECT_EQ(model_.write(dlpc350::kEndpointOut, report.data(), report.size()), TransferOutcome::kDone);
    }
    dlpc350::ReplyAssembler assembler;
    for (;;) {
      std::vector<std::uint8_t> in;
      const TransferOutcome outcome = model_.read(dlpc350::kEndpointIn, 64, in);
      if (outcome != TransferOutcome::kDone) {
        ADD_FAILURE() << "no reply to " << dlpc350::command_name(command);
        return {};
      }
      if (auto reply = assembler.feed(in.data(), in.size())) return *reply;
    }
  }
  bool write(dlpc350::Command command, std::vector<std::uint8_t> data) {
    return !send(false, command, std::move(data)).error;
  }
  std::uint8_t read_byte(dlpc350::Command command) { return send(true, command).data.at(0); }

 private:
  Dlpc350Model& model_;
  std::uint8_t sequence_ = 0;
};

// Writes a LUT of `count` 8-bit patterns from flash images 0.., as the driver does.
void write_sequence(Dlpc350Host& host, int count, bool repeat, std::uint32_t exposure_us = 8333) {
  using namespace dlpc350;
  ASSERT_TRUE(host.write(Command::kPatternStartStop, {0}));
  ASSERT_TRUE(host.write(Command::kDisplayMode, {1}));
  ASSERT_TRUE(host.write(Command::kPatternSource, {3}));
  ASSERT_TRUE(host.write(Command::kPatternTriggerMode, {1}));
  ASSERT_TRUE(host.write(Command::kExposureFramePeriod, encode_exposure({exposure_us, exposure_us})));
  std::vector<LutEntry> entries;
  std::vector<std::uint8_t> images;
  for (int i = 0; i < count; ++i) {
    LutEntry entry;
    entry.pattern_number = static_cast<std::uint8_t>(i % 3);
    entry.buffer_swap = i % 3 == 0;
    entries.push_back(entry);
    if (i % 3 == 0) images.push_back(static_cast<std::uint8_t>(i / 3));
  }
  ASSERT_TRUE(host.write(Command::kPatternConfig,
                         encode_pattern_config({count, repeat, count, static_cast<int>(images.size())})));
  ASSERT_TRUE(host.write(Command::kMailboxControl, {2}));
  ASSERT_TRUE(host.write(Command::kMailboxAddress, {0}));
  ASSERT_TRUE(host.write(Command::kMailboxData, encode_lut_entries(entries)));
  ASSERT_TRUE(host.write(Command::kMailboxControl, {1}));
  ASSERT_TRUE(host.write(Command::kMailboxAddress, {0}));
  ASSERT_TRUE(host.write(Command::kMailboxData, encode_image_lut(images)));
  ASSERT_TRUE(host.write(Command::kMailboxControl, {0}));
}

TEST(Dlpc350Model, AnswersReadsWithItsState) {
  Dlpc350Model model;
  Dlpc350Host host(model);
  const dlpc350::Version version = dlpc350::decode_version(host.send(true, dlpc350::Command::kGetVersion).data);
  EXPECT_EQ(dlpc350::Version::format(version.application), "3.0.0");
  EXPECT_EQ(host.read_byte(dlpc350::Command::kHardwareStatus), 0x01);
  EXPECT_EQ(host.read_byte(dlpc350::Command::kNumImagesInFlash), 16);
  EXPECT_TRUE(host.write(dlpc350::Command::kPowerControl, {1}));
  EXPECT_EQ(host.read_byte(dlpc350::Command::kPowerControl), 1);
  EXPECT_EQ(host.read_byte(dlpc350::Command::kMainStatus) & 0x01, 0x01);  // parked in standby
  EXPECT_FALSE(host.write(dlpc350::Command::kDisplayMode, {1}));          // refused in standby
  EXPECT_TRUE(host.write(dlpc350::Command::kPowerControl, {0}));
  EXPECT_TRUE(host.write(dlpc350::Command::kTrigOut1, dlpc350::encode_trig_out1({true, 0xBB, 0xC0})));
  EXPECT_EQ(dlpc350::decode_trig_out1(host.send(true, dlpc350::Command::kTrigOut1).data),
            (dlpc350::TriggerOutputConfig{true, 0xBB, 0xC0}));
  EXPECT_TRUE(host.send(true, static_cast<dlpc350::Command>(0x1234)).error);  // unknown command: NACK
  EXPECT_FALSE(host.write(dlpc350::Command::kPatternSource, {2}));           // not a valid source
  EXPECT_FALSE(host.write(dlpc350::Command::kTrigOut1, {2, 0, 0}));          // invert byte not 0/1
}

TEST(Dlpc350Model, ValidationPollsBusyThenReportsTheResult) {
  ManualClock clock;
  Dlpc350Model model({}, clock.clock());
  Dlpc350Host host(model);
  write_sequence(host, 22, false);
  EXPECT_FALSE(host.write(dlpc350::Command::kPatternStartStop, {2}));  // not validated yet
  ASSERT_TRUE(host.write(dlpc350::Command::kLutValidate, {0}));
  EXPECT_EQ(host.read_byte(dlpc350::Command::kLutValidate), 0x80);
  EXPECT_EQ(host.read_byte(dlpc350::Command::kLutValidate), 0x80);
  EXPECT_EQ(host.read_byte(dlpc350::Command::kLutValidate), 0x00);
  EXPECT_TRUE(model.state().validated);
  const auto state = model.state();
  EXPECT_EQ(state.pattern_config, (dlpc350::PatternConfig{22, false, 22, 8}));
  EXPECT_EQ(state.pattern_lut[4].pattern_number, 1);
  EXPECT_EQ(state.image_lut[7], 7);
  // The LUT reads back through the mailbox.
  ASSERT_TRUE(host.write(dlpc350::Command::kMailboxControl, {2}));
  ASSERT_TRUE(host.write(dlpc350::Command::kMailboxAddress, {0}));
  const auto lut = dlpc350::decode_lut_entries(host.send(true, dlpc350::Command::kMailboxData).data);
  ASSERT_EQ(lut.size(), 22u);
  EXPECT_TRUE(lut[21].buffer_swap);
}

TEST(Dlpc350Model, ValidationCatchesWhatTheHardwareRejects) {
  Dlpc350Model model({"x", {}, 4, 0});  // 4 images in flash
  Dlpc350Host host(model);
  write_sequence(host, 22, false, 1000);  // 8 images needed; 1000 us is too short for 8-bit patterns
  ASSERT_TRUE(host.write(dlpc350::Command::kLutValidate, {0}));
  const dlpc350::ValidationStatus status{host.read_byte(dlpc350::Command::kLutValidate)};
  EXPECT_FALSE(status.valid());
  EXPECT_NE(status.bits & dlpc350::ValidationStatus::kExposureInvalid, 0);
  EXPECT_NE(status.bits & dlpc350::ValidationStatus::kPatternNumbersInvalid, 0);
  EXPECT_FALSE(host.write(dlpc350::Command::kPatternStartStop, {2}));
}

TEST(Dlpc350Model, TheSequencePlaysOnTheDeviceClock) {
  ManualClock clock;
  Dlpc350Model model({"x", {}, 16, 0}, clock.clock());
  Dlpc350Host host(model);
  write_sequence(host, 7, false);
  ASSERT_TRUE(host.write(dlpc350::Command::kLutValidate, {0}));
  ASSERT_EQ(host.read_byte(dlpc350::Command::kLutValidate), 0);
  EXPECT_FALSE(model.displayed_pattern().has_value());
  ASSERT_TRUE(host.write(dlpc350::Command::kPatternStartStop, {2}));
  EXPECT_FALSE(host.write(dlpc350::Command::kExposureFramePeriod, dlpc350::encode_exposure({9000, 9000})))
      << "settings must not change while the sequence runs";
  for (int frame = 0; frame < 7; ++frame) {
    const auto shown = model.displayed_pattern();
    ASSERT_TRUE(shown.has_value()) << frame;
    EXPECT_EQ(shown->lut_index, frame);
    EXPECT_EQ(shown->flash_image, frame / 3);
    EXPECT_EQ(shown->pattern_number, frame % 3);
    EXPECT_EQ(model.trigger_out1_pulses(), static_cast<std::uint64_t>(frame + 1));
    clock.advance_us(8333);
  }
  EXPECT_FALSE(model.displayed_pattern().has_value()) << "a non-repeating sequence ends after its last pattern";
  EXPECT_EQ(model.trigger_out1_pulses(), 7u);
  EXPECT_EQ(host.read_byte(dlpc350::Command::kMainStatus) & 0x02, 0);  // sequencer stopped by itself
}

TEST(Dlpc350Model, PauseHoldsThePatternAndStartResumesIt) {
  ManualClock clock;
  Dlpc350Model model({"x", {}, 16, 0}, clock.clock());
  Dlpc350Host host(model);
  write_sequence(host, 6, true);
  ASSERT_TRUE(host.write(dlpc350::Command::kLutValidate, {0}));
  ASSERT_EQ(host.read_byte(dlpc350::Command::kLutValidate), 0);
  ASSERT_TRUE(host.write(dlpc350::Command::kPatternStartStop, {2}));
  clock.advance_us(2 * 8333 + 100);
  ASSERT_TRUE(host.write(dlpc350::Command::kPatternStartStop, {1}));
  clock.advance_us(100 * 8333);
  EXPECT_EQ(model.displayed_pattern()->lut_index, 2);
  EXPECT_EQ(model.trigger_out1_pulses(), 3u);
  ASSERT_TRUE(host.write(dlpc350::Command::kPatternStartStop, {2}));
  EXPECT_EQ(model.displayed_pattern()->lut_index, 2);  // re-displayed
  clock.advance_us(5 * 8333);
  EXPECT_EQ(model.displayed_pattern()->lut_index, 1) << "a repeating sequence wraps";
  ASSERT_TRUE(host.write(dlpc350::Command::kPatternStartStop, {0}));
  EXPECT_FALSE(model.displayed_pattern().has_value());
}

TEST(Dlpc350Model, FaultInjection) {
  Dlpc350Model model;
  const dlpc350::Report report =
      dlpc350::encode_request({true, true, 1, static_cast<std::uint16_t>(dlpc350::Command::kMainStatus), {}})[0];
  std::vector<std::uint8_t> in;
  model.set_behaviour(Behaviour::kStallOnce);
  EXPECT_EQ(model.write(dlpc350::kEndpointOut, report.data(), report.size()), TransferOutcome::kStall);
  EXPECT_EQ(model.write(dlpc350::kEndpointOut, report.data(), report.size()), TransferOutcome::kStall)
      << "halted until the host clears it";
  model.clear_halt(dlpc350::kEndpointOut);
  EXPECT_EQ(model.write(dlpc350::kEndpointOut, report.data(), report.size()), TransferOutcome::kDone);
  EXPECT_EQ(model.read(dlpc350::kEndpointIn, 64, in), TransferOutcome::kDone);
  model.set_behaviour(Behaviour::kSilent);
  EXPECT_EQ(model.write(dlpc350::kEndpointOut, report.data(), report.size()), TransferOutcome::kDone);
  EXPECT_EQ(model.read(dlpc350::kEndpointIn, 64, in), TransferOutcome::kPending);
  model.set_behaviour(Behaviour::kUnplugged);
  EXPECT_EQ(model.read(dlpc350::kEndpointIn, 64, in), TransferOutcome::kNoDevice);
  model.set_behaviour(Behaviour::kNormal);
  EXPECT_EQ(model.read(dlpc350::kEndpointIn, 64, in), TransferOutcome::kPending) << "the silent period lost its reply";
  model.refuse(dlpc350::Command::kMainStatus);
  Dlpc350Host host(model);
  EXPECT_TRUE(host.send(true, dlpc350::Command::kMainStatus).error);
  // A malformed report gets a NACK addressed to its sequence number.
  const std::uint8_t garbage[] = {0xC0, 0x33, 0xFF, 0xFF};
  EXPECT_EQ(model.write(dlpc350::kEndpointOut, garbage, sizeof garbage), TransferOutcome::kDone);
  ASSERT_EQ(model.read(dlpc350::kEndpointIn, 64, in), TransferOutcome::kDone);
  const dlpc350::Reply nack = dlpc350::decode_reply(in.data(), in.size());
  EXPECT_TRUE(nack.error);
  EXPECT_EQ(nack.sequence, 0x33);
}

// ---- head controller -----------------------------------------------------------------------
class HeadctlHost {
 public:
  explicit HeadctlHost(HeadctlModel& model) : model_(model) {}
  std::vector<std::uint8_t> exchange(const std::vector<std::uint8_t>& frame) {
    EXPECT_EQ(model_.write(HEADCTL_USB_ENDPOINT_OUT, frame.data(), frame.size()), TransferOutcome::kDone);
    std::vector<std::uint8_t> in;
    EXPECT_EQ(model_.read(HEADCTL_USB_ENDPOINT_IN, 512, in), TransferOutcome::kDone);
    return in;
  }
  headctl::Reply send(const headctl::Request& request) {
    const std::vector<std::uint8_t> in = exchange(headctl::encode_request(++sequence_, request));
    const headctl::Frame frame = headctl::decode_frame(in.data(), in.size());
    EXPECT_EQ(frame.sequence, sequence_);
    return headctl::decode_reply(frame);
  }
  template <typename T>
  T expect(const headctl::Request& request) {
    headctl::Reply reply = send(request);
    if (auto* error = std::get_if<headctl::ErrorReply>(&reply)) {
      ADD_FAILURE() << headctl::device_error_name(error->code) << ": " << error->text;
      return T{};
    }
    return std::get<T>(reply);
  }
  headctl::DeviceError refusal(const headctl::Request& request) {
    const headctl::Reply reply = send(request);
    if (const auto* error = std::get_if<headctl::ErrorReply>(&reply)) return error->code;
    ADD_FAILURE() << headctl::message_type_name(headctl::type_of(request)) << " was not refused";
    return headctl::DeviceError::kBadFrame;
  }

 private:
  HeadctlModel& model_;
  std::uint8_t sequence_ = 0;
};

HeadctlModelOptions table_options() {
  HeadctlModelOptions options;
  options.steps_per_revolution = 6400;
  options.default_speed_steps_per_s = 6400;
  options.home_switch_step = 1234;
  return options;
}

TEST(HeadctlModel, HomesAndMovesOnTheDeviceClock) {
  using namespace headctl;
  ManualClock clock;
  HeadctlModel model(table_options(), clock.clock());
  HeadctlHost host(model);
  EXPECT_EQ(host.expect<IdentifyReply>(IdentifyRequest{}).steps_per_revolution, 6400u);
  EXPECT_EQ(host.refusal(TurntableMoveRequest{100, Direction::kShortest, 0}), DeviceError::kNotHomed);
  host.expect<Acknowledge>(TurntableHomeRequest{});
  EXPECT_EQ(host.expect<TurntableStatusReply>(TurntableStatusRequest{}).state, TurntableState::kHoming);
  clock.advance_us(1234 * 1'000'000 / 6400 + 1000);  // the index is 1234 steps away
  TurntableStatusReply status = host.expect<TurntableStatusReply>(TurntableStatusRequest{});
  EXPECT_EQ(status.state, TurntableState::kIdle);
  EXPECT_TRUE(status.homed);
  EXPECT_EQ(status.position_step, 0u);

  host.expect<Acknowledge>(TurntableMoveRequest{1600, Direction::kShortest, 0});
  clock.advance_us(125'000);  // half way at 6400 steps/s
  EXPECT_EQ(host.expect<TurntablePositionReply>(TurntablePositionRequest{}).position_step, 800u);
  EXPECT_EQ(host.refusal(TurntableMoveRequest{0, Direction::kShortest, 0}), DeviceError::kBusy);
  clock.advance_us(125'000);
  EXPECT_EQ(host.expect<TurntablePositionReply>(TurntablePositionRequest{}).position_step, 1600u);
  // The shortest way from 1600 to 6000 is backwards through 0.
  host.expect<Acknowledge>(TurntableMoveRequest{6000, Direction::kShortest, 0});
  clock.advance_us(1'000'000 * 1000 / 6400);
  EXPECT_EQ(host.expect<TurntablePositionReply>(TurntablePositionRequest{}).position_step, 600u);
  clock.advance_us(1'000'000);
  EXPECT_EQ(host.expect<TurntablePositionReply>(TurntablePositionRequest{}).position_step, 6000u);
  EXPECT_EQ(host.refusal(TurntableMoveRequest{6400, Direction::kShortest, 0}), DeviceError::kOutOfRange);
}

TEST(HeadctlModel, FiresArmedTriggerSequences) {
  using namespace headctl;
  ManualClock clock;
  HeadctlModel model(table_options(), clock.clock());
  HeadctlHost host(model);
  EXPECT_EQ(host.refusal(TriggerFireRequest{}), DeviceError::kInvalidState);
  EXPECT_EQ(host.refusal(TriggerArmRequest{0x01, TriggerSource::kHost, 2, 0}), DeviceError::kInvalidState)
      << "output 0 is not enabled yet";
  host.expect<Acknowledge>(TriggerConfigureRequest{0, true, Polarity::kActiveHigh, 100, 0});
  host.expect<Acknowledge>(TriggerConfigureRequest{2, true, Polarity::kActiveLow, 50, 10});
  EXPECT_EQ(host.refusal(TriggerConfigureRequest{4, true, Polarity::kActiveHigh, 100, 0}), DeviceError::kOutOfRange);
  host.expect<Acknowledge>(TriggerArmRequest{0x05, TriggerSource::kHost, 2, 0});
  const auto first = host.expect<TriggerFireReply>(TriggerFireRequest{});
  EXPECT_EQ(first.pulse_index, 0);
  EXPECT_EQ(first.remaining, 1);
  const auto second = host.expect<TriggerFireReply>(TriggerFireRequest{});
  EXPECT_EQ(second.pulse_index, 1);
  EXPECT_EQ(second.remaining, 0);
  EXPECT_EQ(host.refusal(TriggerFireRequest{}), DeviceError::kInvalidState) << "the sequence disarmed itself";
  EXPECT_EQ(model.pulses_on_output(0), 2u);
  EXPECT_EQ(model.pulses_on_output(1), 0u);
  EXPECT_EQ(model.pulses_on_output(2), 2u);
  // Timer source: the first pulse at once, then one per period.
  host.expect<Acknowledge>(TriggerArmRequest{0x01, TriggerSource::kTimer, 4, 1000});
  EXPECT_EQ(host.expect<TriggerStatusReply>(TriggerStatusRequest{}).fired, 1);
  clock.advance_us(1500);
  EXPECT_EQ(host.expect<TriggerStatusReply>(TriggerStatusRequest{}).fired, 2);
  clock.advance_us(10'000);
  const auto done = host.expect<TriggerStatusReply>(TriggerStatusRequest{});
  EXPECT_FALSE(done.armed);
  EXPECT_EQ(done.total_pulses, 6u);
  EXPECT_EQ(model.pulses_on_output(0), 6u);
}

TEST(HeadctlModel, ARetriedRequestIsAnsweredFromTheCacheNotExecutedTwice) {
  using namespace headctl;
  HeadctlModel model(table_options());
  HeadctlHost host(model);
  host.expect<Acknowledge>(TriggerConfigureRequest{0, true, Polarity::kActiveHigh, 100, 0});
  host.expect<Acknowledge>(TriggerArmRequest{0x01, TriggerSource::kHost, 5, 0});
  const std::vector<std::uint8_t> fire = encode_request(200, TriggerFireRequest{});
  const std::vector<std::uint8_t> first = host.exchange(fire);
  const std::vector<std::uint8_t> again = host.exchange(fire);
  EXPECT_EQ(first, again);
  EXPECT_EQ(model.pulses_on_output(0), 1u);
  const auto executed = model.executed();
  EXPECT_EQ(std::count(executed.begin(), executed.end(), MessageType::kTriggerFire), 1);
  const auto received = model.received();
  EXPECT_EQ(std::count(received.begin(), received.end(), MessageType::kTriggerFire), 2);
}

TEST(HeadctlModel, AnswersBadFramesWithTheProtocolsErrors) {
  using namespace headctl;
  HeadctlModel model(table_options());
  HeadctlHost host(model);
  auto error_of = [&](std::vector<std::uint8_t> bytes) {
    const std::vector<std::uint8_t> in = host.exchange(bytes);
    const Frame frame = decode_frame(in.data(), in.size());
    const Reply reply = decode_reply(frame);
    EXPECT_TRUE(std::holds_alternative<ErrorReply>(reply));
    return std::make_pair(frame.sequence, std::get<ErrorReply>(reply).code);
  };
  std::vector<std::uint8_t> bad_crc = encode_request(17, TurntableStatusRequest{});
  bad_crc.back() ^= 0x01;
  EXPECT_EQ(error_of(bad_crc), std::make_pair(std::uint8_t{17}, DeviceError::kBadFrame));
  std::vector<std::uint8_t> version2 = encode_request(18, IdentifyRequest{});
  version2[HEADCTL_FRAME_OFF_VERSION] = 2;
  EXPECT_EQ(error_of(version2), std::make_pair(std::uint8_t{18}, DeviceError::kUnsupportedVersion));
  Frame unknown;
  unknown.type = 0x77;
  unknown.sequence = 19;
  EXPECT_EQ(error_of(encode_frame(unknown)), std::make_pair(std::uint8_t{19}, DeviceError::kUnknownMessage));
  Frame short_move;
  short_move.type = HEADCTL_MSG_TURNTABLE_MOVE;
  short_move.sequence = 20;
  short_move.payload = {1, 2, 3};
  EXPECT_EQ(error_of(encode_frame(short_move)), std::make_pair(std::uint8_t{20}, DeviceError::kBadPayload));
  const auto log = host.expect<ErrorLogReply>(ErrorLogRequest{});
  ASSERT_EQ(log.entries.size(), 4u);
  EXPECT_EQ(log.entries[0].code, DeviceError::kBadFrame);
  EXPECT_EQ(log.entries[2].type, 0x77);
  EXPECT_EQ(log.entries[3].sequence, 20);
  host.expect<Acknowledge>(ErrorClearRequest{});
  EXPECT_TRUE(host.expect<ErrorLogReply>(ErrorLogRequest{}).entries.empty());
}

TEST(HeadctlModel, InjectedFaultsLatchAndClear) {
  using namespace headctl;
  ManualClock clock;
  HeadctlModel model(table_options(), clock.clock());
  HeadctlHost host(model);
  host.expect<Acknowledge>(TurntableHomeRequest{});
  clock.advance_us(1'000'000);
  model.stall_next_move_after(100);
  host.expect<Acknowledge>(TurntableMoveRequest{3200, Direction::kPositive, 0});
  clock.advance_us(1'000'000);
  TurntableStatusReply status = host.expect<TurntableStatusReply>(TurntableStatusRequest{});
  EXPECT_EQ(status.state, TurntableState::kFault);
  EXPECT_EQ(status.fault, Fault::kMotorStall);
  EXPECT_EQ(status.position_step, 100u);
  EXPECT_FALSE(status.homed);
  EXPECT_EQ(host.refusal(TurntableMoveRequest{0, Direction::kShortest, 0}), DeviceError::kHardwareFault);
  host.expect<Acknowledge>(TurntableHomeRequest{});  // re-homing clears the stall
  clock.advance_us(2'000'000);
  EXPECT_EQ(host.expect<TurntableStatusReply>(TurntableStatusRequest{}).state, TurntableState::kIdle);

  model.remove_home_switch(true);
  host.expect<Acknowledge>(TurntableHomeRequest{});
  clock.advance_us(2'000'000);  // one whole revolution without finding the index
  EXPECT_EQ(host.expect<TurntableStatusReply>(TurntableStatusRequest{}).fault, Fault::kHomeNotFound);
  model.remove_home_switch(false);

  model.set_temperature(1, 91.5);
  EXPECT_EQ(host.expect<TemperaturesReply>(TemperaturesRequest{}).sensors.at(1).centi_celsius, 9150);
  EXPECT_EQ(host.expect<TurntableStatusReply>(TurntableStatusRequest{}).fault, Fault::kOverTemperature);
  host.expect<Acknowledge>(ErrorClearRequest{});
  EXPECT_EQ(host.expect<TurntableStatusReply>(TurntableStatusRequest{}).fault, Fault::kOverTemperature)
      << "still too hot: the fault latches again";
  model.set_temperature(1, 40.0);
  host.expect<Acknowledge>(ErrorClearRequest{});
  EXPECT_EQ(host.expect<TurntableStatusReply>(TurntableStatusRequest{}).fault, Fault::kNone);
}

}  // namespace
}  // namespace sls::fwif::models
