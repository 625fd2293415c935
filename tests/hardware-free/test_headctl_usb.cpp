// The head-controller driver against the emulated board through real libusb (umockdev):
// homing, moves and positions, trigger sequences, retries that never execute a request twice,
// the board's errors and faults, and clear errors within the timeout when it stalls or stops
// answering.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <thread>

#include "drivers/headctl/head_controller.h"
#include "drivers/usb/usb_scanner_devices.h"
#include "tests/hardware-free/usb_test_bench.h"

namespace sls::test {
namespace {

using namespace fwif::headctl;
using drivers::HeadController;
using drivers::HeadControllerOptions;
using HeadctlUsbTest = UsbDevicesTest;
using std::chrono::milliseconds;

constexpr const char* kBoardName = "head controller 1209:5ca1 on bus 1 address 3 (serial HC-EMU-0001)";

fwif::models::HeadctlModelOptions fast_table() {
  fwif::models::HeadctlModelOptions options;
  options.steps_per_revolution = 6400;
  options.default_speed_steps_per_s = 32000;  // a revolution in 0.2 s keeps the tests short
  options.home_switch_step = 5000;
  return options;
}

std::size_t count(const std::vector<MessageType>& types, MessageType type) {
  return static_cast<std::size_t>(std::count(types.begin(), types.end(), type));
}

TEST_F(HeadctlUsbTest, OpensAndIdentifiesTheBoard) {
  plug({}, fast_table());
  auto board = HeadController::open("headctl://");
  EXPECT_EQ(board->name(), kBoardName);
  EXPECT_EQ(board->uri(), "headctl://1:3");
  const IdentifyReply& id = board->identity();
  EXPECT_EQ(id.protocol_version, HEADCTL_PROTOCOL_VERSION);
  EXPECT_EQ(id.serial, "HC-EMU-0001");
  EXPECT_EQ(id.trigger_outputs, 4);
  EXPECT_EQ(board->steps_per_revolution(), 6400);
  const std::vector<Temperature> temperatures = board->temperatures();
  ASSERT_EQ(temperatures.size(), 2u);
  EXPECT_DOUBLE_EQ(temperatures[1].celsius(), 42.1);
  EXPECT_EQ(HeadController::open("headctl://1:3?serial=HC-EMU-0001")->uri(), "headctl://1:3");
}

TEST_F(HeadctlUsbTest, ABoardWithAnOemsOwnIdsIsListedAndOpenedByItsUri) {
  plug({}, fast_table());
  fwif::models::HeadctlModelOptions oem = fast_table();
  oem.vendor_id = 0x1234;
  oem.product_id = 0x0042;
  oem.serial = "OEM-7";
  bus_->plug(std::make_shared<fwif::models::HeadctlModel>(oem), 2, 9);
  const auto devices = drivers::usb::list_usb_scanner_devices({{0x1234, 0x0042}});
  ASSERT_EQ(devices.size(), 3u);
  EXPECT_EQ(devices[2].uri, "headctl://2:9?vid=0x1234&pid=0x0042");
  EXPECT_EQ(devices[2].usb.serial, "OEM-7");
  auto board = HeadController::open(devices[2].uri);
  EXPECT_EQ(board->identity().serial, "OEM-7");
  EXPECT_EQ(board->name(), "head controller 1234:0042 on bus 2 address 9 (serial OEM-7)");
  EXPECT_EQ(drivers::usb::list_usb_scanner_devices().size(), 2u) << "unknown IDs are not listed";
}

TEST_F(HeadctlUsbTest, HomesMovesAndReportsThePosition) {
  plug({}, fast_table());
  auto board = HeadController::open("headctl://");
  board->home(milliseconds{2000});
  EXPECT_DOUBLE_EQ(board->position_deg(), 0.0);
  EXPECT_TRUE(head_model_->turntable().homed);

  const auto start = std::chrono::steady_clock::now();
  board->move_to_deg(90.0, milliseconds{2000});
  const double move_ms = elapsed_ms(start);
  EXPECT_DOUBLE_EQ(board->position_deg(), 90.0);
  EXPECT_EQ(head_model_->turntable().position_step, 1600u);
  EXPECT_GE(move_ms, 45.0) << "1600 steps at 32000 steps/s take 50 ms: the driver waited for the move";
  board->move_to_deg(-45.0, milliseconds{2000});  // the same as 315 degrees
  EXPECT_DOUBLE_EQ(board->position_deg(), 315.0);
  EXPECT_EQ(head_model_->turntable().position_step, 5600u);
  board->move_to_step(10, Direction::kPositive, milliseconds{2000});
  EXPECT_EQ(board->turntable_status().position_step, 10u);
  const auto executed = head_model_->executed();
  EXPECT_EQ(count(executed, MessageType::kTurntableMove), 3u);
  EXPECT_GE(count(executed, MessageType::kTurntableStatus), 4u) << "the driver polls the status while it moves";
}

TEST_F(HeadctlUsbTest, ConfiguresArmsAndFiresTriggerOutputs) {
  plug({}, fast_table());
  auto board = HeadController::open("headctl://");
  board->configure_trigger({0, true, Polarity::kActiveHigh, 100, 0});
  board->configure_trigger({1, true, Polarity::kActiveLow, 200, 50});
  board->arm_triggers({0x03, TriggerSource::kHost, 3, 0});
  for (std::uint16_t i = 0; i < 3; ++i) {
    const TriggerFireReply fired = board->fire_trigger();
    EXPECT_EQ(fired.pulse_index, i);
    EXPECT_EQ(fired.remaining, 2 - i);
  }
  EXPECT_EQ(head_model_->pulses_on_output(0), 3u);
  EXPECT_EQ(head_model_->pulses_on_output(1), 3u);
  EXPECT_EQ(head_model_->pulses_on_output(2), 0u);
  const std::string message = error_message([&] { board->fire_trigger(); }, ErrorCode::kDevice);
  EXPECT_NE(message.find(std::string(kBoardName) + ": TRIGGER_FIRE refused: INVALID_STATE"), std::string::npos)
      << message;
  // A sequence on the board's own timer.
  board->arm_triggers({0x01, TriggerSource::kTimer, 5, 2000});
  std::this_thread::sleep_for(milliseconds{40});
  const TriggerStatusReply status = board->trigger_status();
  EXPECT_FALSE(status.armed);
  EXPECT_EQ(status.total_pulses, 3u + 5u);  // pulses of the sequences, not per output
  EXPECT_EQ(head_model_->pulses_on_output(0), 8u);
  board->arm_triggers({0x01, TriggerSource::kHost, 10, 0});
  board->disarm_triggers();
  EXPECT_FALSE(board->trigger_status().armed);
}

TEST_F(HeadctlUsbTest, ALostReplyIsRetriedWithoutFiringTwice) {
  plug({}, fast_table());
  HeadControllerOptions options;
  options.retry = {milliseconds{300}, 3};
  auto board = HeadController::open("headctl://", options);
  board->configure_trigger({0, true, Polarity::kActiveHigh, 100, 0});
  board->arm_triggers({0x01, TriggerSource::kHost, 4, 0});
  head_model_->drop_next_replies(1);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(board->fire_trigger().pulse_index, 0);
  EXPECT_GE(elapsed_ms(start), 90.0) << "the first attempt waited for its reply";
  head_model_->corrupt_next_replies(1);
  EXPECT_EQ(board->fire_trigger().pulse_index, 1) << "a corrupt reply is retried too";
  EXPECT_EQ(head_model_->pulses_on_output(0), 2u);
  EXPECT_EQ(count(head_model_->received(), MessageType::kTriggerFire), 4u);
  EXPECT_EQ(count(head_model_->executed(), MessageType::kTriggerFire), 2u);
}

TEST_F(HeadctlUsbTest, TheBoardsRefusalsBecomeErrorCodes) {
  plug({}, fast_table());
  auto board = HeadController::open("headctl://");
  const std::string not_homed = error_message([&] { board->move_to_deg(10.0, milliseconds{500}); }, ErrorCode::kDevice);
  EXPECT_NE(not_homed.find("TURNTABLE_MOVE refused: NOT_HOMED"), std::string::npos) << not_homed;
  error_message([&] { board->configure_trigger({7, true, Polarity::kActiveHigh, 100, 0}); },
                ErrorCode::kInvalidArgument);  // OUT_OF_RANGE: the board has 4 outputs
  error_message([&] { board->move_to_step(6400, Direction::kShortest, milliseconds{100}); },
                ErrorCode::kInvalidArgument);  // caught before it goes out
  board->home(milliseconds{2000});
  board->transact(TurntableMoveRequest{3200, Direction::kPositive, 1000});  // 3.2 s at 1000 steps/s
  const std::string busy =
      error_message([&] { board->transact(TurntableMoveRequest{0, Direction::kShortest, 0}); }, ErrorCode::kBusy);
  EXPECT_NE(busy.find("BUSY"), std::string::npos) << busy;
  board->stop_turntable();
  const std::vector<ErrorLogEntry> log = board->error_log();
  ASSERT_EQ(log.size(), 3u);
  EXPECT_EQ(log[0].code, DeviceError::kNotHomed);
  EXPECT_EQ(log[1].code, DeviceError::kOutOfRange);
  EXPECT_EQ(log[2].code, DeviceError::kBusy);
  board->clear_errors();
  EXPECT_TRUE(board->error_log().empty());
}

TEST_F(HeadctlUsbTest, FaultsAreReportedWithTheirCause) {
  plug({}, fast_table());
  auto board = HeadController::open("headctl://");
  board->home(milliseconds{2000});
  head_model_->stall_next_move_after(500);
  const std::string stall = error_message([&] { board->move_to_deg(180.0, milliseconds{2000}); }, ErrorCode::kDevice);
  EXPECT_NE(stall.find("turntable fault MOTOR_STALL while moving to 180.000 deg (step 3200)"), std::string::npos)
      << stall;
  EXPECT_NE(stall.find(kBoardName), std::string::npos) << stall;
  head_model_->remove_home_switch(true);
  const std::string home = error_message([&] { board->home(milliseconds{2000}); }, ErrorCode::kDevice);
  EXPECT_NE(home.find("HOME_NOT_FOUND while homing"), std::string::npos) << home;
  head_model_->remove_home_switch(false);
  board->home(milliseconds{2000});  // homing again clears the fault
  head_model_->set_temperature(0, 95.0);
  const std::string hot = error_message([&] { board->move_to_deg(10.0, milliseconds{500}); }, ErrorCode::kDevice);
  EXPECT_NE(hot.find("HARDWARE_FAULT"), std::string::npos) << hot;
}

TEST_F(HeadctlUsbTest, AMoveThatTakesTooLongTimesOutAndStopsTheTable) {
  fwif::models::HeadctlModelOptions slow = fast_table();
  plug({}, slow);
  auto board = HeadController::open("headctl://");
  board->home(milliseconds{2000});
  const auto start = std::chrono::steady_clock::now();
  const std::string message = error_message(
      [&] { board->move_to_step(3200, Direction::kPositive, milliseconds{150}, 2000); }, ErrorCode::kTimeout);
  const double ms = elapsed_ms(start);
  EXPECT_GE(ms, 150.0);
  EXPECT_LT(ms, 150.0 + 1000.0);
  EXPECT_NE(message.find(std::string(kBoardName) + ": moving to 180.000 deg (step 3200) not done within 150 ms"),
            std::string::npos)
      << message;
  const TurntableStatusReply status = head_model_->turntable();
  EXPECT_EQ(status.state, TurntableState::kIdle) << "the driver stopped the table";
  EXPECT_GT(status.position_step, 0u);
  EXPECT_LT(status.position_step, 3200u);
}

TEST_F(HeadctlUsbTest, AStalledOrSilentBoardIsAClearErrorWithinTheTimeout) {
  plug({}, fast_table());
  HeadControllerOptions options;
  options.retry = {milliseconds{300}, 3};
  auto board = HeadController::open("headctl://", options);

  head_model_->set_behaviour(fwif::models::Behaviour::kStall);
  auto start = std::chrono::steady_clock::now();
  const std::string stalled = error_message([&] { board->position_deg(); }, ErrorCode::kDevice);
  const double stall_ms = elapsed_ms(start);
  EXPECT_LT(stall_ms, 300 + 1000);
  std::printf("[ measured ] stalled head controller: kDevice after %.1f ms\n", stall_ms);
  EXPECT_NE(stalled.find(std::string(kBoardName) + ": TURNTABLE_POSITION failed: endpoint 0x01 stalled (LIBUSB_ERROR_PIPE)"),
            std::string::npos)
      << stalled;

  head_model_->set_behaviour(fwif::models::Behaviour::kSilent);
  start = std::chrono::steady_clock::now();
  const std::string silent = error_message([&] { board->turntable_status(); }, ErrorCode::kTimeout);
  const double ms = elapsed_ms(start);
  EXPECT_GE(ms, 250.0);
  EXPECT_LT(ms, 300 + 1000);
  EXPECT_NE(silent.find(std::string(kBoardName) + ": TURNTABLE_STATUS failed: endpoint 0x81 gave no reply within 100 ms"),
            std::string::npos)
      << silent;
  std::printf("[ measured ] silent head controller: kTimeout after %.0f ms (budget 300 ms)\n", ms);

  head_model_->set_behaviour(fwif::models::Behaviour::kUnplugged);
  const std::string gone = error_message([&] { board->temperatures(); }, ErrorCode::kDevice);
  EXPECT_NE(gone.find("disconnected during TEMPERATURES"), std::string::npos) << gone;
}

}  // namespace
}  // namespace sls::test
