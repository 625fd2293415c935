// The DLPC350 driver against the emulated controller through real libusb (umockdev): the
// bytes on the wire, the LUT written and validated, patterns on the DMD, and clear errors
// within the timeout when the controller stalls, falls silent or is unplugged.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <thread>
#include <vector>

#include "drivers/dlpc350/dlpc350_projector.h"
#include "drivers/usb/usb_scanner_devices.h"
#include "sdk/decode/pattern_set.h"
#include "tests/hardware-free/usb_test_bench.h"

namespace sls::test {
namespace {

using namespace fwif::dlpc350;
using drivers::Dlpc350Options;
using drivers::Dlpc350Projector;
using Dlpc350UsbTest = UsbDevicesTest;

constexpr const char* kProjectorName = "DLPC350 0451:6401 on bus 1 address 2 (serial LCR4500-EMU-0001)";

// The last request with this command the controller received.
Request last(const fwif::models::Dlpc350Model& model, Command command) {
  const std::vector<Request> requests = model.requests();
  const auto it = std::find_if(requests.rbegin(), requests.rend(),
                               [command](const Request& r) { return r.command == static_cast<std::uint16_t>(command); });
  if (it == requests.rend()) {
    ADD_FAILURE() << "no " << command_name(command) << " on the wire";
    return {};
  }
  return *it;
}

std::vector<std::uint8_t> head_of(const Report& report, std::size_t count) {
  return {report.begin(), report.begin() + static_cast<std::ptrdiff_t>(count)};
}

TEST_F(Dlpc350UsbTest, OpensAndIdentifiesTheController) {
  plug();
  auto projector = Dlpc350Projector::open("dlpc350://");
  EXPECT_EQ(projector->name(), kProjectorName);
  const drivers::ProjectorInfo info = projector->info();
  EXPECT_EQ(info.uri, "dlpc350://1:2");
  EXPECT_EQ(info.firmware, "application 3.0.0, API 2.0.0");
  EXPECT_EQ(info.width, 912);
  EXPECT_EQ(info.height, 1140);
  // The first report on the wire: GET_VERSION read, sequence 0, length 2, CMD3 CMD2.
  const std::vector<Report> reports = projector_model_->reports();
  ASSERT_FALSE(reports.empty());
  EXPECT_EQ(head_of(reports[0], 7), (std::vector<std::uint8_t>{0xC0, 0x00, 0x02, 0x00, 0x05, 0x02, 0x00}));
  const Dlpc350Projector::Status status = projector->status();
  EXPECT_TRUE(status.hardware.initialized());
  EXPECT_TRUE(status.system.memory_test_passed());
  EXPECT_FALSE(status.main.sequence_running());
  EXPECT_EQ(projector->flash_image_count(), 16);
}

TEST_F(Dlpc350UsbTest, PowerModesTriggersAndExposureOnTheWire) {
  plug();
  auto projector = Dlpc350Projector::open("dlpc350://1:2");
  projector->set_power(PowerMode::kStandby);
  EXPECT_EQ(projector_model_->state().power, PowerMode::kStandby);
  EXPECT_EQ(projector->power(), PowerMode::kStandby);
  const Report standby = projector_model_->reports()[projector_model_->reports().size() - 2];
  EXPECT_EQ(standby[0], 0x40);  // write with acknowledgement
  EXPECT_EQ(head_of(standby, 7)[2], 3);
  EXPECT_EQ(std::vector<std::uint8_t>(standby.begin() + 4, standby.begin() + 7), (std::vector<std::uint8_t>{0x00, 0x02, 0x01}));
  projector->set_power(PowerMode::kNormal);

  projector->set_display_mode(DisplayMode::kPattern);
  projector->set_pattern_source(PatternSource::kFlash);
  projector->set_trigger_mode(TriggerMode::kInternalOrExternal);
  projector->configure_trigger_output(1, {false, trigger_delay_code(1.0), trigger_delay_code(-2.0)});
  projector->configure_trigger_output(2, {true, trigger_delay_code(0.5), kTriggerDelayZero});
  projector->set_exposure({10000, 10500});
  EXPECT_EQ(last(*projector_model_, Command::kDisplayMode).data, std::vector<std::uint8_t>{1});
  EXPECT_EQ(last(*projector_model_, Command::kPatternSource).data, std::vector<std::uint8_t>{3});
  EXPECT_EQ(last(*projector_model_, Command::kPatternTriggerMode).data, std::vector<std::uint8_t>{1});
  EXPECT_EQ(last(*projector_model_, Command::kTrigOut1).data,
            (std::vector<std::uint8_t>{0, trigger_delay_code(1.0), trigger_delay_code(-2.0)}));
  EXPECT_EQ(last(*projector_model_, Command::kExposureFramePeriod).data,
            (std::vector<std::uint8_t>{0x10, 0x27, 0, 0, 0x04, 0x29, 0, 0}));
  const auto state = projector_model_->state();
  EXPECT_EQ(state.display_mode, DisplayMode::kPattern);
  EXPECT_EQ(state.pattern_source, PatternSource::kFlash);
  EXPECT_EQ(state.trigger_mode, TriggerMode::kInternalOrExternal);
  EXPECT_TRUE(state.trig_out2.active_low);
  EXPECT_EQ(projector->exposure(), (ExposureTiming{10000, 10500}));
  EXPECT_THROW(projector->configure_trigger_output(3, {}), Error);
}

TEST_F(Dlpc350UsbTest, LoadPatternsWritesAndValidatesTheSequenceLut) {
  plug();
  auto projector = Dlpc350Projector::open("dlpc350://");
  const PatternSet set = make_gray_phase_pattern_set();
  ASSERT_EQ(set.size(), 22u);
  projector->load_patterns(set);
  EXPECT_EQ(projector->patterns(), set);
  EXPECT_EQ(projector->current_pattern(), -1);

  const auto state = projector_model_->state();
  EXPECT_EQ(state.display_mode, DisplayMode::kPattern);
  EXPECT_EQ(state.pattern_source, PatternSource::kFlash);
  EXPECT_EQ(state.exposure, (ExposureTiming{8333, 8333}));
  EXPECT_EQ(state.pattern_config, (PatternConfig{22, false, 22, 8}));
  EXPECT_TRUE(state.validated);
  EXPECT_EQ(state.sequence, SequenceAction::kStop);
  EXPECT_EQ(state.mailbox, Mailbox::kClosed);
  for (int i = 0; i < 22; ++i) {
    const LutEntry& entry = state.pattern_lut[static_cast<std::size_t>(i)];
    EXPECT_EQ(entry.pattern_number, i % 3) << i;
    EXPECT_EQ(entry.bit_depth, 8);
    EXPECT_EQ(entry.leds, kLedWhite);
    EXPECT_EQ(entry.trigger, LutTrigger::kInternal);
    EXPECT_EQ(entry.buffer_swap, i % 3 == 0) << i;
  }
  for (int image = 0; image < 8; ++image) EXPECT_EQ(state.image_lut[static_cast<std::size_t>(image)], image);

  // 22 entries are 66 data bytes: one MBOX_DATA message over two reports.
  const Request lut = [&] {
    for (const Request& r : projector_model_->requests()) {
      if (r.command == static_cast<std::uint16_t>(Command::kMailboxData) && r.data.size() == 66) return r;
    }
    ADD_FAILURE() << "no 66-byte MBOX_DATA";
    return Request{};
  }();
  EXPECT_EQ(decode_lut_entries(lut.data).size(), 22u);
  const std::vector<Report> reports = projector_model_->reports();
  const auto first = std::find_if(reports.begin(), reports.end(), [](const Report& r) {
    return r[0] == 0x40 && r[2] == 68 && r[3] == 0 && r[4] == 0x34 && r[5] == 0x1A;
  });
  ASSERT_NE(first, reports.end());
  ASSERT_NE(first + 1, reports.end());
  EXPECT_EQ((*(first + 1))[0], lut.data[58]) << "the continuation report carries data byte 58 on";
  // Validation was polled until the controller was done.
  const auto requests = projector_model_->requests();
  EXPECT_GE(std::count_if(requests.begin(), requests.end(),
                          [](const Request& r) { return r.read && r.command == 0x1A1A; }),
            3);
  // And the LUT reads back as written.
  const std::vector<LutEntry> back = projector->read_pattern_lut(22);
  EXPECT_EQ(back, std::vector<LutEntry>(state.pattern_lut.begin(), state.pattern_lut.begin() + 22));
}

TEST_F(Dlpc350UsbTest, ShowPatternPutsThePatternOnTheDmd) {
  plug();
  auto projector = Dlpc350Projector::open("dlpc350://");
  EXPECT_THROW(projector->show_pattern(0), Error);  // nothing loaded yet
  projector->load_patterns(make_gray_phase_pattern_set());
  for (const int index : {0, 13, 21, 2}) {
    projector->show_pattern(index);
    EXPECT_EQ(projector->current_pattern(), index);
    const auto shown = projector_model_->displayed_pattern();
    ASSERT_TRUE(shown.has_value()) << index;
    EXPECT_EQ(shown->flash_image, index / 3);
    EXPECT_EQ(shown->pattern_number, index % 3);
    EXPECT_EQ(shown->bit_depth, 8);
    EXPECT_EQ(drivers::dlpc350_pattern_index({shown->flash_image, shown->pattern_number}, 0), index);
    EXPECT_TRUE(projector->status().main.sequence_running());
    // PAT_START_STOP start: flags, sequence, length 3, CMD3 0x24, CMD2 0x1A, action 2.
    const Request start = last(*projector_model_, Command::kPatternStartStop);
    EXPECT_EQ(start.data, std::vector<std::uint8_t>{2});
  }
  EXPECT_THROW(projector->show_pattern(22), Error);
  projector->go_dark();
  EXPECT_EQ(projector->current_pattern(), -1);
  EXPECT_FALSE(projector_model_->displayed_pattern().has_value());
  EXPECT_EQ(last(*projector_model_, Command::kPatternStartStop).data, std::vector<std::uint8_t>{0});
}

TEST(Dlpc350FlashLayout, PatternsFillTheGreenRedAndBluePlanesOfConsecutiveImages) {
  const PatternSet set = make_gray_phase_pattern_set();
  const std::vector<std::array<int, 3>> layout = drivers::dlpc350_flash_layout(set);
  ASSERT_EQ(layout.size(), 8u);
  EXPECT_EQ(layout[0], (std::array<int, 3>{0, 1, 2}));
  EXPECT_EQ(layout[7], (std::array<int, 3>{21, -1, -1}));
  for (int index = 0; index < 22; ++index) {
    const drivers::Dlpc350FlashSlot slot = drivers::dlpc350_flash_slot(index, 5);
    EXPECT_EQ(slot.flash_image, 5 + index / 3);
    EXPECT_EQ(drivers::dlpc350_pattern_index(slot, 5), index);
  }
  EXPECT_EQ(drivers::dlpc350_pattern_index({4, 0}, 5), -1);
}

TEST_F(Dlpc350UsbTest, PlaySequenceRunsTheWholeSetOnce) {
  plug();
  auto projector = Dlpc350Projector::open("dlpc350://");
  projector->load_patterns(make_gray_phase_pattern_set());
  projector->show_pattern(5);  // leaves a one-pattern LUT that play_sequence must replace
  projector->go_dark();        // stops its pulses, so the count below is the sequence's alone
  const std::uint64_t pulses_before = projector_model_->trigger_out1_pulses();
  const auto start = std::chrono::steady_clock::now();
  projector->play_sequence();
  const int early = projector->current_pattern();
  if (elapsed_ms(start) < 150.0) {  // well inside the 183 ms the sequence lasts (a loaded machine may be slower)
    EXPECT_GE(early, 0);
    EXPECT_LT(early, 22);
  }
  EXPECT_EQ(projector_model_->state().pattern_config.lut_entries, 22);
  std::this_thread::sleep_for(std::chrono::milliseconds(22 * 8333 / 1000 + 150));
  EXPECT_EQ(projector->current_pattern(), -1);
  EXPECT_FALSE(projector_model_->displayed_pattern().has_value());
  EXPECT_EQ(projector_model_->trigger_out1_pulses() - pulses_before, 22u) << "one TRIG_OUT1 pulse per pattern";
}

TEST_F(Dlpc350UsbTest, SetsThatDoNotFitAreRefusedBeforeTouchingTheController) {
  fwif::models::Dlpc350ModelOptions small_flash;
  small_flash.flash_images = 4;
  plug(small_flash);
  auto projector = Dlpc350Projector::open("dlpc350://");
  GrayPhaseOptions xga;
  xga.projector_width = 1024;
  xga.projector_height = 768;
  EXPECT_NE(error_message([&] { projector->load_patterns(make_gray_phase_pattern_set(xga)); },
                          ErrorCode::kInvalidArgument)
                .find("912 x 1140"),
            std::string::npos);
  const std::string flash = error_message([&] { projector->load_patterns(make_gray_phase_pattern_set()); },
                                          ErrorCode::kInvalidArgument);
  EXPECT_NE(flash.find("flash images 0 to 7"), std::string::npos) << flash;
  EXPECT_NE(flash.find(kProjectorName), std::string::npos) << flash;
  EXPECT_EQ(projector->patterns().size(), 0u);
}

TEST_F(Dlpc350UsbTest, AnInvalidSequenceIsReportedAsTheControllerSaysIt) {
  plug();
  Dlpc350Options options;
  options.timing = {1000, 1000};  // far too short for 8-bit patterns
  auto projector = Dlpc350Projector::open("dlpc350://", options);
  const std::string message =
      error_message([&] { projector->load_patterns(make_gray_phase_pattern_set()); }, ErrorCode::kDevice);
  EXPECT_NE(message.find("exposure or frame period invalid"), std::string::npos) << message;
  EXPECT_EQ(projector->patterns().size(), 0u);
}

TEST_F(Dlpc350UsbTest, ARefusedCommandIsNamed) {
  plug();
  auto projector = Dlpc350Projector::open("dlpc350://");
  projector_model_->refuse(Command::kPatternTriggerMode);
  const std::string message =
      error_message([&] { projector->load_patterns(make_gray_phase_pattern_set()); }, ErrorCode::kDevice);
  EXPECT_NE(message.find("refused write PAT_TRIG_MODE (0x1A23)"), std::string::npos) << message;
  EXPECT_NE(message.find(kProjectorName), std::string::npos) << message;
}

TEST_F(Dlpc350UsbTest, AStallThatClearsIsRetried) {
  plug();
  auto projector = Dlpc350Projector::open("dlpc350://");
  projector_model_->set_behaviour(fwif::models::Behaviour::kStallOnce);
  EXPECT_EQ(Version::format(projector->version().application), "3.0.0");
}

TEST_F(Dlpc350UsbTest, AStalledEndpointIsAClearErrorWithinTheTimeout) {
  plug();
  Dlpc350Options options;
  options.retry = {std::chrono::milliseconds{300}, 3};
  auto projector = Dlpc350Projector::open("dlpc350://", options);
  projector_model_->set_behaviour(fwif::models::Behaviour::kStall);
  const auto start = std::chrono::steady_clock::now();
  const std::string message = error_message([&] { projector->status(); }, ErrorCode::kDevice);
  const double ms = elapsed_ms(start);
  EXPECT_LT(ms, 300 + 1000);
  std::printf("[ measured ] stalled DLPC350: kDevice after %.1f ms\n", ms);
  EXPECT_NE(message.find(kProjectorName), std::string::npos) << message;
  EXPECT_NE(message.find("STATUS_HW"), std::string::npos) << message;
  EXPECT_NE(message.find("stalled (LIBUSB_ERROR_PIPE)"), std::string::npos) << message;
  EXPECT_NE(message.find("3 attempt(s)"), std::string::npos) << message;
}

TEST_F(Dlpc350UsbTest, ASilentControllerTimesOutWithinTheTimeout) {
  plug();
  Dlpc350Options options;
  options.retry = {std::chrono::milliseconds{300}, 3};
  auto projector = Dlpc350Projector::open("dlpc350://", options);
  projector_model_->set_behaviour(fwif::models::Behaviour::kSilent);
  const auto start = std::chrono::steady_clock::now();
  const std::string message = error_message([&] { projector->version(); }, ErrorCode::kTimeout);
  const double ms = elapsed_ms(start);
  EXPECT_GE(ms, 250.0) << "each of the 3 attempts waits its 100 ms";
  EXPECT_LT(ms, 300 + 1000);
  EXPECT_NE(message.find(kProjectorName), std::string::npos) << message;
  EXPECT_NE(message.find("GET_VERSION (0x0205)"), std::string::npos) << message;
  EXPECT_NE(message.find("gave no reply within 100 ms"), std::string::npos) << message;
  std::printf("[ measured ] silent DLPC350: kTimeout after %.0f ms (budget 300 ms)\n", ms);
  // Once the controller answers again the driver goes on, ignoring nothing it should not.
  projector_model_->set_behaviour(fwif::models::Behaviour::kNormal);
  EXPECT_EQ(Version::format(projector->version().application), "3.0.0");
}

TEST_F(Dlpc350UsbTest, AnUnpluggedControllerIsNamed) {
  plug();
  auto projector = Dlpc350Projector::open("dlpc350://");
  projector_model_->set_behaviour(fwif::models::Behaviour::kUnplugged);
  const std::string message = error_message([&] { projector->go_dark(); }, ErrorCode::kDevice);
  EXPECT_NE(message.find(std::string(kProjectorName) + ": disconnected during PAT_START_STOP"), std::string::npos)
      << message;
}

TEST_F(Dlpc350UsbTest, EnumerationAndOpeningBySerialOrAddress) {
  plug();
  const std::vector<drivers::usb::UsbScannerDevice> devices = drivers::usb::list_usb_scanner_devices();
  ASSERT_EQ(devices.size(), 2u);
  EXPECT_EQ(devices[0].kind, drivers::usb::UsbScannerDeviceKind::kDlpc350Projector);
  EXPECT_EQ(devices[0].uri, "dlpc350://1:2");
  EXPECT_EQ(devices[0].usb.serial, "LCR4500-EMU-0001");
  EXPECT_EQ(devices[0].usb.manufacturer, "Texas Instruments");
  EXPECT_EQ(devices[1].kind, drivers::usb::UsbScannerDeviceKind::kHeadController);
  EXPECT_EQ(devices[1].uri, "headctl://1:3");
  EXPECT_NE(devices[1].description.find("HC-EMU-0001"), std::string::npos) << devices[1].description;

  EXPECT_EQ(Dlpc350Projector::open(devices[0].uri)->info().uri, "dlpc350://1:2");
  EXPECT_EQ(Dlpc350Projector::open("dlpc350://?serial=LCR4500-EMU-0001")->info().uri, "dlpc350://1:2");
  EXPECT_NE(error_message([] { Dlpc350Projector::open("dlpc350://?serial=NOPE"); }, ErrorCode::kNotFound)
                .find("serial NOPE"),
            std::string::npos);
  error_message([] { Dlpc350Projector::open("dlpc350://1:3"); }, ErrorCode::kNotFound);  // the head controller
  error_message([] { Dlpc350Projector::open("dlpc350://bus4"); }, ErrorCode::kInvalidArgument);
  error_message([] { Dlpc350Projector::open("headctl://"); }, ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace sls::test
