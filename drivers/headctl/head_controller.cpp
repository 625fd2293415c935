#include "drivers/headctl/head_controller.h"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <thread>

#include "sdk/core/error.h"

namespace sls::drivers {

using namespace fwif::headctl;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

namespace {

// Read buffer: a whole frame, rounded up to full 64-byte packets so a frame never overflows it.
constexpr std::size_t kReadCapacity = 256;
static_assert(kReadCapacity >= HEADCTL_MAX_FRAME_SIZE && kReadCapacity % 64 == 0);

milliseconds remaining_until(Clock::time_point deadline) {
  return std::max(milliseconds{1}, std::chrono::duration_cast<milliseconds>(deadline - Clock::now()));
}

ErrorCode error_code_for(DeviceError error) {
  switch (error) {
    case DeviceError::kBusy: return ErrorCode::kBusy;
    case DeviceError::kOutOfRange:
    case DeviceError::kBadPayload: return ErrorCode::kInvalidArgument;
    case DeviceError::kUnsupportedVersion: return ErrorCode::kVersionMismatch;
    case DeviceError::kUnknownMessage: return ErrorCode::kUnsupported;
    default: return ErrorCode::kDevice;
  }
}

}  // namespace

HeadController::HeadController(std::unique_ptr<usb::UsbConnection> connection, HeadControllerOptions options,
                               std::string uri)
    : connection_(std::move(connection)), options_(std::move(options)), uri_(std::move(uri)) {}

HeadController::~HeadController() = default;

const std::string& HeadController::name() const { return connection_->name(); }
const std::string& HeadController::uri() const { return uri_; }
const IdentifyReply& HeadController::identity() const { return identity_; }

Reply HeadController::transact(const Request& request) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const MessageType type = type_of(request);
  const std::uint8_t sequence = next_sequence_++;
  const std::vector<std::uint8_t> frame_bytes = encode_request(sequence, request);
  const milliseconds attempt_timeout = options_.retry.attempt_timeout();
  ErrorCode failure = ErrorCode::kTimeout;
  std::string problem;
  auto failed = [&](const usb::TransferResult& result, std::uint8_t endpoint) {
    return connection_->transfer_failed(result, endpoint, attempt_timeout, message_type_name(type), &failure, &problem);
  };

  // PROTOCOL.md "Retries": every attempt sends the same bytes (same sequence number).
  for (int attempt = 0; attempt < options_.retry.attempts; ++attempt) {
    const Clock::time_point deadline = Clock::now() + attempt_timeout;
    if (failed(connection_->write(HEADCTL_USB_ENDPOINT_OUT, frame_bytes.data(), frame_bytes.size(),
                                  remaining_until(deadline)),
               HEADCTL_USB_ENDPOINT_OUT)) {
      continue;
    }
    for (;;) {
      std::array<std::uint8_t, kReadCapacity> buffer{};
      const usb::TransferResult result =
          connection_->read(HEADCTL_USB_ENDPOINT_IN, buffer.data(), buffer.size(), remaining_until(deadline));
      if (failed(result, HEADCTL_USB_ENDPOINT_IN)) break;
      Reply reply;
      std::uint8_t reply_sequence = 0;
      try {
        const Frame frame = decode_frame(buffer.data(), result.transferred);
        reply_sequence = frame.sequence;
        if (frame.sequence == sequence) reply = decode_reply(frame);
      } catch (const Error& error) {
        if (error.code() == ErrorCode::kVersionMismatch) throw_error(error.code(), "{}: {}", name(), error.what());
        failure = ErrorCode::kDevice;
        problem = fmt::format("corrupt reply: {}", error.what());
        break;
      }
      if (reply_sequence != sequence) {  // a late reply to an earlier request
        if (Clock::now() < deadline) continue;
        failure = ErrorCode::kTimeout;
        problem = fmt::format("only replies to earlier requests arrived within {} ms", attempt_timeout.count());
        break;
      }
      if (const auto* refused = std::get_if<ErrorReply>(&reply)) {
        if (refused->code == DeviceError::kBadFrame) {  // the board could not read our frame: send it again
          failure = ErrorCode::kDevice;
          problem = fmt::format("the board reported BAD_FRAME ({})", refused->text);
          break;
        }
        throw_error(error_code_for(refused->code), "{}: {} refused: {} (detail {}): {}", name(),
                    message_type_name(type), device_error_name(refused->code), refused->detail, refused->text);
      }
      if (reply_type(reply) != static_cast<std::uint8_t>(type)) {
        failure = ErrorCode::kDevice;
        problem = fmt::format("the reply is to {}", message_type_name(reply_type(reply)));
        break;
      }
      return reply;
    }
  }
  throw_error(failure, "{}: {} failed: {} ({} attempt(s), {} ms in all)", name(), message_type_name(type), problem,
              options_.retry.attempts, options_.retry.attempts * attempt_timeout.count());
}

template <typename T>
T HeadController::expect(const Request& request) const {
  Reply reply = transact(request);
  if (auto* typed = std::get_if<T>(&reply)) return std::move(*typed);
  throw_error(ErrorCode::kDevice, "{}: {} got a reply of the wrong kind", name(), message_type_name(type_of(request)));
}

void HeadController::require_turntable() const {
  if ((identity_.capabilities & HEADCTL_CAP_TURNTABLE) == 0 || identity_.steps_per_revolution == 0) {
    throw_error(ErrorCode::kUnsupported, "{}: the board has no turntable", name());
  }
}

void HeadController::configure_trigger(const TriggerConfigureRequest& config) { expect<Acknowledge>(config); }
void HeadController::arm_triggers(const TriggerArmRequest& sequence) { expect<Acknowledge>(sequence); }
TriggerFireReply HeadController::fire_trigger() { return expect<TriggerFireReply>(TriggerFireRequest{}); }
TriggerStatusReply HeadController::trigger_status() { return expect<TriggerStatusReply>(TriggerStatusRequest{}); }
void HeadController::disarm_triggers() { expect<Acknowledge>(TriggerDisarmRequest{}); }

TurntableStatusReply HeadController::turntable_status() const {
  return expect<TurntableStatusReply>(TurntableStatusRequest{});
}

void HeadController::stop_turntable() { expect<Acknowledge>(TurntableStopRequest{}); }

template <typename Done>
void HeadController::wait_for_turntable(Done done, Clock::time_point deadline, milliseconds timeout,
                                        const std::string& goal) {
  for (;;) {
    const TurntableStatusReply status = turntable_status();
    if (status.state == TurntableState::kFault || status.fault != Fault::kNone) {
      throw_error(ErrorCode::kDevice, "{}: turntable fault {} while {} (at step {} of {})", name(),
                  fault_name(status.fault), goal, status.position_step, status.steps_per_revolution);
    }
    if (done(status)) return;
    if (Clock::now() >= deadline) {
      try {
        stop_turntable();  // do not leave it running towards a goal the caller gave up on
      } catch (const Error&) {
      }
      throw_error(ErrorCode::kTimeout, "{}: {} not done within {} ms; the table is {} at step {} of {}", name(), goal,
                  timeout.count(), turntable_state_name(status.state), status.position_step,
                  status.steps_per_revolution);
    }
    std::this_thread::sleep_for(options_.poll_interval);
  }
}

void HeadController::home(milliseconds timeout) {
  require_turntable();
  const Clock::time_point deadline = Clock::now() + timeout;
  expect<Acknowledge>(TurntableHomeRequest{});
  wait_for_turntable([](const TurntableStatusReply& s) { return s.state == TurntableState::kIdle && s.homed; },
                     deadline, timeout, "homing");
}

void HeadController::move_to_step(std::uint32_t step, Direction direction, milliseconds timeout,
                                  std::uint32_t speed_steps_per_s) {
  require_turntable();
  if (step >= identity_.steps_per_revolution) {
    throw_error(ErrorCode::kInvalidArgument, "{}: step {} is outside the revolution of {} steps", name(), step,
                identity_.steps_per_revolution);
  }
  const Clock::time_point deadline = Clock::now() + timeout;
  expect<Acknowledge>(TurntableMoveRequest{step, direction, speed_steps_per_s});
  const double degrees = step * 360.0 / identity_.steps_per_revolution;
  wait_for_turntable(
      [step](const TurntableStatusReply& s) { return s.state == TurntableState::kIdle && s.position_step == step; },
      deadline, timeout, fmt::format("moving to {:.3f} deg (step {})", degrees, step));
}

void HeadController::move_to_deg(double angle_deg, milliseconds timeout) {
  require_turntable();
  if (!std::isfinite(angle_deg)) throw_error(ErrorCode::kInvalidArgument, "{}: angle {} deg", name(), angle_deg);
  double turn = std::fmod(angle_deg, 360.0);
  if (turn < 0.0) turn += 360.0;
  const std::uint32_t revolution = identity_.steps_per_revolution;
  const auto step = static_cast<std::uint32_t>(std::llround(turn / 360.0 * revolution) % revolution);
  move_to_step(step, Direction::kShortest, timeout);
}

double HeadController::position_deg() const {
  require_turntable();
  const auto reply = expect<TurntablePositionReply>(TurntablePositionRequest{});
  if (reply.steps_per_revolution == 0) throw_error(ErrorCode::kDevice, "{}: reports 0 steps per revolution", name());
  return reply.position_step * 360.0 / reply.steps_per_revolution;
}

int HeadController::steps_per_revolution() const { return static_cast<int>(identity_.steps_per_revolution); }

std::vector<Temperature> HeadController::temperatures() {
  return expect<TemperaturesReply>(TemperaturesRequest{}).sensors;
}

std::vector<ErrorLogEntry> HeadController::error_log() { return expect<ErrorLogReply>(ErrorLogRequest{}).entries; }

void HeadController::clear_errors() { expect<Acknowledge>(ErrorClearRequest{}); }

std::unique_ptr<HeadController> HeadController::open(const usb::UsbSelector& selector, HeadControllerOptions options) {
  auto connection = usb::UsbConnection::open(selector, HEADCTL_USB_INTERFACE_NUMBER, "head controller");
  const std::string uri = fmt::format("headctl://{}:{}", connection->info().bus, connection->info().address);
  std::unique_ptr<HeadController> controller(new HeadController(std::move(connection), std::move(options), uri));
  controller->identity_ = controller->expect<IdentifyReply>(IdentifyRequest{});
  if (controller->identity_.protocol_version != HEADCTL_PROTOCOL_VERSION) {
    throw_error(ErrorCode::kVersionMismatch, "{}: speaks protocol version {}, this SDK version {}", controller->name(),
                controller->identity_.protocol_version, HEADCTL_PROTOCOL_VERSION);
  }
  return controller;
}

std::unique_ptr<HeadController> HeadController::open(const std::string& uri, HeadControllerOptions options) {
  const DeviceUri parsed = parse_device_uri(uri);
  if (parsed.scheme != "headctl") throw_error(ErrorCode::kInvalidArgument, "{} is not a headctl:// URI", uri);
  return open(usb::usb_selector_from_uri(parsed, HEADCTL_USB_VENDOR_ID, HEADCTL_USB_PRODUCT_ID), std::move(options));
}

}  // namespace sls::drivers
