#include "firmware-interface/models/headctl_model.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <type_traits>

#include "sdk/core/error.h"

namespace sls::fwif::models {

using namespace headctl;

namespace {

constexpr std::uint32_t kMaxPulseWidthUs = 1'000'000;
constexpr std::uint32_t kMaxDelayUs = 1'000'000;

std::string clip_text(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (out.size() == HEADCTL_MAX_ERROR_TEXT) break;
    out.push_back(c >= 0x20 && c <= 0x7E ? c : '?');
  }
  return out;
}

}  // namespace

HeadctlModel::HeadctlModel(HeadctlModelOptions options, DeviceClock clock)
    : options_(std::move(options)), clock_(std::move(clock)), temperatures_(options_.temperatures) {
  if (options_.trigger_outputs > HEADCTL_MAX_TRIGGER_OUTPUTS || options_.steps_per_revolution == 0 ||
      options_.temperatures.size() > HEADCTL_MAX_TEMPERATURE_SENSORS) {
    throw_error(ErrorCode::kInvalidArgument, "head controller model: {} outputs, {} steps per revolution, {} sensors",
                options_.trigger_outputs, options_.steps_per_revolution, options_.temperatures.size());
  }
  for (std::uint8_t i = 0; i < HEADCTL_MAX_TRIGGER_OUTPUTS; ++i) {
    outputs_[i].output = i;
    outputs_[i].enabled = false;
  }
}

UsbIdentity HeadctlModel::identity() const {
  UsbIdentity id;
  id.vendor_id = options_.vendor_id;
  id.product_id = options_.product_id;
  id.manufacturer = "slscan";
  id.product = options_.model;
  id.serial = options_.serial;
  id.interface_class = HEADCTL_USB_INTERFACE_CLASS;
  id.endpoints = {{HEADCTL_USB_ENDPOINT_IN, EndpointType::kBulk, 64, 0},
                  {HEADCTL_USB_ENDPOINT_OUT, EndpointType::kBulk, 64, 0}};
  return id;
}

TurntableStatusReply HeadctlModel::turntable() {
  std::lock_guard<std::mutex> lock(mutex_);
  advance();
  return turntable_locked();
}

std::uint64_t HeadctlModel::pulses_on_output(int output) {
  std::lock_guard<std::mutex> lock(mutex_);
  advance();
  if (output < 0 || output >= static_cast<int>(pulses_.size())) return 0;
  return pulses_[static_cast<std::size_t>(output)];
}

std::vector<MessageType> HeadctlModel::received() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return received_;
}

std::vector<MessageType> HeadctlModel::executed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return executed_;
}

void HeadctlModel::set_temperature(std::uint8_t sensor, double celsius) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (Temperature& t : temperatures_) {
    if (t.sensor == sensor) t.centi_celsius = static_cast<std::int16_t>(std::lround(celsius * 100.0));
  }
}

void HeadctlModel::latch_fault(Fault fault) {
  std::lock_guard<std::mutex> lock(mutex_);
  advance();
  if (motion_) {  // a fault stops the motor where it is
    absolute_step_ = absolute_now();
    motion_.reset();
  }
  fault_ = fault;
}

void HeadctlModel::stall_next_move_after(std::uint32_t steps) {
  std::lock_guard<std::mutex> lock(mutex_);
  stall_next_move_after_ = steps;
}

void HeadctlModel::remove_home_switch(bool removed) {
  std::lock_guard<std::mutex> lock(mutex_);
  home_switch_removed_ = removed;
}

void HeadctlModel::drop_next_replies(int count) {
  std::lock_guard<std::mutex> lock(mutex_);
  drop_replies_ = count;
}

void HeadctlModel::corrupt_next_replies(int count) {
  std::lock_guard<std::mutex> lock(mutex_);
  corrupt_replies_ = count;
}

TransferOutcome HeadctlModel::handle_write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size) {
  if (endpoint != HEADCTL_USB_ENDPOINT_OUT) return TransferOutcome::kStall;
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::uint8_t> bytes(data, data + size);
  current_sequence_ = 0;
  current_type_ = size > HEADCTL_FRAME_OFF_TYPE ? data[HEADCTL_FRAME_OFF_TYPE] : 0;
  peek_sequence(data, size, &current_sequence_);
  received_.push_back(static_cast<MessageType>(current_type_));

  // PROTOCOL.md "Retries": the same frame again is a retry of a request whose reply was lost;
  // send the reply again rather than, say, firing a second trigger pulse.
  if (!last_request_.empty() && bytes == last_request_) {
    queue(last_reply_);
    return TransferOutcome::kDone;
  }

  Reply reply;
  try {
    const Frame frame = decode_frame(data, size);
    if (frame.is_reply() || frame.is_error()) {
      reply = refuse(DeviceError::kBadFrame, 0, "a request must not carry the reply or error flag");
    } else if (!is_known_message_type(frame.type)) {
      reply = refuse(DeviceError::kUnknownMessage, frame.type, "unknown message type");
    } else {
      Request request;
      bool decoded = false;
      try {
        request = decode_request(frame);
        decoded = true;
      } catch (const Error& error) {
        reply = refuse(DeviceError::kBadPayload, 0, clip_text(error.what()));
      }
      if (decoded) {
        advance();
        executed_.push_back(type_of(request));
        reply = execute(request, frame.sequence);
      }
    }
  } catch (const Error& error) {
    if (error.code() == ErrorCode::kVersionMismatch) {
      reply = refuse(DeviceError::kUnsupportedVersion, HEADCTL_PROTOCOL_VERSION, "protocol version not supported");
    } else {
      reply = refuse(DeviceError::kBadFrame, 0, clip_text(error.what()));
    }
  }
  std::vector<std::uint8_t> frame = encode_reply(current_sequence_, reply);
  last_request_ = std::move(bytes);
  last_reply_ = frame;
  queue(std::move(frame));
  return TransferOutcome::kDone;
}

TransferOutcome HeadctlModel::handle_read(std::uint8_t endpoint, std::size_t capacity, std::vector<std::uint8_t>& out) {
  if (endpoint != HEADCTL_USB_ENDPOINT_IN) return TransferOutcome::kStall;
  std::lock_guard<std::mutex> lock(mutex_);
  if (replies_.empty()) return TransferOutcome::kPending;
  std::vector<std::uint8_t>& frame = replies_.front();
  out.assign(frame.begin(), frame.begin() + static_cast<std::ptrdiff_t>(std::min(capacity, frame.size())));
  replies_.pop_front();
  return TransferOutcome::kDone;
}

void HeadctlModel::queue(std::vector<std::uint8_t> frame) {
  if (drop_replies_ > 0) {
    --drop_replies_;
    return;
  }
  if (corrupt_replies_ > 0) {
    --corrupt_replies_;
    frame.back() ^= 0xFF;  // the CRC's last byte
  }
  replies_.push_back(std::move(frame));
}

Reply HeadctlModel::refuse(DeviceError code, std::uint32_t detail, std::string text) {
  ErrorLogEntry entry;
  entry.code = code;
  entry.type = current_type_;
  entry.sequence = current_sequence_;
  entry.detail = detail;
  entry.timestamp_ms = static_cast<std::uint32_t>(clock_() / 1000);
  error_log_.push_back(entry);
  while (error_log_.size() > HEADCTL_MAX_ERROR_LOG_ENTRIES) error_log_.pop_front();
  return ErrorReply{current_type_, code, detail, clip_text(text)};
}

Reply HeadctlModel::execute(const Request& request, std::uint8_t sequence) {
  current_sequence_ = sequence;
  const std::int64_t now = clock_();
  return std::visit(
      [&](const auto& r) -> Reply {
        using T = std::decay_t<decltype(r)>;
        if constexpr (std::is_same_v<T, IdentifyRequest>) {
          IdentifyReply id;
          id.firmware_major = options_.firmware_major;
          id.firmware_minor = options_.firmware_minor;
          id.firmware_patch = options_.firmware_patch;
          id.hardware_revision = options_.hardware_revision;
          id.trigger_outputs = options_.trigger_outputs;
          id.temperature_sensors = static_cast<std::uint8_t>(temperatures_.size());
          id.capabilities = HEADCTL_CAP_TRIGGERS | HEADCTL_CAP_TURNTABLE | HEADCTL_CAP_TEMPERATURES;
          id.steps_per_revolution = options_.steps_per_revolution;
          id.serial = options_.serial;
          id.model = options_.model;
          return id;
        } else if constexpr (std::is_same_v<T, TriggerConfigureRequest>) {
          if (r.output >= options_.trigger_outputs) {
            return refuse(DeviceError::kOutOfRange, options_.trigger_outputs, fmt::format("output {}", r.output));
          }
          if (armed_) return refuse(DeviceError::kInvalidState, 0, "a trigger sequence is armed");
          if (r.pulse_width_us == 0 || r.pulse_width_us > kMaxPulseWidthUs) {
            return refuse(DeviceError::kOutOfRange, kMaxPulseWidthUs, "pulse width");
          }
          if (r.delay_us > kMaxDelayUs) return refuse(DeviceError::kOutOfRange, kMaxDelayUs, "delay");
          outputs_[r.output] = r;
          return Acknowledge{T::kType};
        } else if constexpr (std::is_same_v<T, TriggerArmRequest>) {
          const auto all = static_cast<std::uint8_t>((1u << options_.trigger_outputs) - 1u);
          if (r.output_mask == 0 || (r.output_mask & ~all) != 0) {
            return refuse(DeviceError::kOutOfRange, all, "output mask");
          }
          if (r.count == 0) return refuse(DeviceError::kOutOfRange, 1, "pulse count");
          std::uint32_t shortest_period = 1;
          for (std::uint8_t i = 0; i < options_.trigger_outputs; ++i) {
            if ((r.output_mask & (1u << i)) == 0) continue;
            if (!outputs_[i].enabled) return refuse(DeviceError::kInvalidState, i, fmt::format("output {} is disabled", i));
            shortest_period = std::max(shortest_period, outputs_[i].pulse_width_us + outputs_[i].delay_us + 1);
          }
          if (r.source == TriggerSource::kTimer && r.period_us < shortest_period) {
            return refuse(DeviceError::kOutOfRange, shortest_period, "period shorter than delay + pulse");
          }
          armed_ = Armed{r.output_mask, r.source, r.count, r.period_us, now, 0};
          advance();  // a timer sequence fires its first pulse now
          return Acknowledge{T::kType};
        } else if constexpr (std::is_same_v<T, TriggerFireRequest>) {
          if (!armed_) return refuse(DeviceError::kInvalidState, 0, "no trigger sequence armed");
          if (armed_->source != TriggerSource::kHost) {
            return refuse(DeviceError::kInvalidState, 0, "the armed sequence runs on the board timer");
          }
          TriggerFireReply fire;
          fire.pulse_index = armed_->fired;
          fire_pulses(armed_->output_mask, 1);
          ++armed_->fired;
          fire.remaining = static_cast<std::uint16_t>(armed_->count - armed_->fired);
          fire.timestamp_us = static_cast<std::uint64_t>(now);
          if (fire.remaining == 0) armed_.reset();
          return fire;
        } else if constexpr (std::is_same_v<T, TriggerStatusRequest>) {
          TriggerStatusReply status;
          status.total_pulses = total_pulses_;
          if (armed_) {
            status.armed = true;
            status.output_mask = armed_->output_mask;
            status.fired = armed_->fired;
            status.remaining = static_cast<std::uint16_t>(armed_->count - armed_->fired);
          }
          return status;
        } else if constexpr (std::is_same_v<T, TriggerDisarmRequest>) {
          armed_.reset();
          return Acknowledge{T::kType};
        } else if constexpr (std::is_same_v<T, TurntableHomeRequest>) {
          if (fault_ == Fault::kOverTemperature) return refuse(DeviceError::kHardwareFault, static_cast<std::uint32_t>(fault_), "over temperature");
          if (motion_) return refuse(DeviceError::kBusy, 0, "the turntable is moving");
          fault_ = Fault::kNone;
          homed_ = false;
          Motion home;
          home.start_us = now;
          home.start_absolute = absolute_step_;
          home.distance = home_switch_removed_
                              ? std::int64_t{options_.steps_per_revolution}
                              : std::int64_t{wrap(std::int64_t{options_.home_switch_step} - absolute_step_)};
          home.speed = options_.default_speed_steps_per_s;
          home.homing = true;
          motion_ = home;
          speed_ = home.speed;
          target_step_ = 0;
          advance();
          return Acknowledge{T::kType};
        } else if constexpr (std::is_same_v<T, TurntableMoveRequest>) {
          if (fault_ != Fault::kNone) return refuse(DeviceError::kHardwareFault, static_cast<std::uint32_t>(fault_), fault_name(fault_));
          if (motion_) return refuse(DeviceError::kBusy, 0, "the turntable is moving");
          if (!homed_) return refuse(DeviceError::kNotHomed, 0, "home the turntable first");
          if (r.target_step >= options_.steps_per_revolution) {
            return refuse(DeviceError::kOutOfRange, options_.steps_per_revolution - 1, "target step");
          }
          if (r.speed_steps_per_s > options_.max_speed_steps_per_s) {
            return refuse(DeviceError::kOutOfRange, options_.max_speed_steps_per_s, "speed");
          }
          const std::uint32_t here = position_locked();
          const std::int64_t forward = wrap(std::int64_t{r.target_step} - here);
          const std::int64_t backward = wrap(std::int64_t{here} - r.target_step);
          Motion move;
          move.start_us = now;
          move.start_absolute = absolute_step_;
          move.distance = r.direction == Direction::kPositive   ? forward
                          : r.direction == Direction::kNegative ? -backward
                          : forward <= backward                 ? forward
                                                                : -backward;
          move.speed = r.speed_steps_per_s == 0 ? options_.default_speed_steps_per_s : r.speed_steps_per_s;
          move.stall_after = stall_next_move_after_;
          stall_next_move_after_.reset();
          target_step_ = r.target_step;
          speed_ = move.speed;
          if (move.distance != 0) motion_ = move;
          advance();
          return Acknowledge{T::kType};
        } else if constexpr (std::is_same_v<T, TurntableStopRequest>) {
          if (motion_) {
            absolute_step_ = absolute_now();
            motion_.reset();
          }
          return Acknowledge{T::kType};
        } else if constexpr (std::is_same_v<T, TurntableStatusRequest>) {
          return turntable_locked();
        } else if constexpr (std::is_same_v<T, TurntablePositionRequest>) {
          return TurntablePositionReply{position_locked(), options_.steps_per_revolution};
        } else if constexpr (std::is_same_v<T, TemperaturesRequest>) {
          return TemperaturesReply{temperatures_};
        } else if constexpr (std::is_same_v<T, ErrorLogRequest>) {
          return ErrorLogReply{{error_log_.begin(), error_log_.end()}};
        } else {
          static_assert(std::is_same_v<T, ErrorClearRequest>);
          error_log_.clear();
          fault_ = Fault::kNone;
          advance();  // a sensor still over its limit latches the fault again
          return Acknowledge{T::kType};
        }
      },
      request);
}

void HeadctlModel::advance() {
  const std::int64_t now = clock_();
  if (motion_) {
    const std::int64_t length = std::llabs(motion_->distance);
    const std::int64_t sign = motion_->distance < 0 ? -1 : 1;
    const std::int64_t travelled = std::min<std::int64_t>(length, (now - motion_->start_us) * motion_->speed / 1'000'000);
    if (motion_->stall_after && *motion_->stall_after < length && travelled >= *motion_->stall_after) {
      absolute_step_ = motion_->start_absolute + sign * *motion_->stall_after;
      motion_.reset();
      fault_ = Fault::kMotorStall;
      homed_ = false;  // a stalled stepper has lost its position
    } else if (travelled == length) {
      absolute_step_ = motion_->start_absolute + motion_->distance;
      if (motion_->homing) {
        if (home_switch_removed_) {
          fault_ = Fault::kHomeNotFound;
        } else {
          zero_absolute_ = absolute_step_;
          homed_ = true;
        }
      }
      motion_.reset();
    }
  }
  if (armed_ && armed_->source == TriggerSource::kTimer) {
    const std::int64_t period = std::max<std::int64_t>(1, armed_->period_us);
    const auto due = static_cast<std::uint16_t>(
        std::min<std::int64_t>(armed_->count, 1 + (now - armed_->armed_at_us) / period));
    if (due > armed_->fired) {
      fire_pulses(armed_->output_mask, due - armed_->fired);
      armed_->fired = due;
    }
    if (armed_->fired == armed_->count) armed_.reset();
  }
  for (const Temperature& t : temperatures_) {
    if (t.centi_celsius > options_.over_temperature_centi_celsius && fault_ != Fault::kOverTemperature) {
      fault_ = Fault::kOverTemperature;
      if (motion_) {
        absolute_step_ = absolute_now();
        motion_.reset();
      }
    }
  }
}

void HeadctlModel::fire_pulses(std::uint8_t mask, std::uint64_t count) {
  for (std::size_t i = 0; i < pulses_.size(); ++i) {
    if ((mask & (1u << i)) != 0) pulses_[i] += count;
  }
  total_pulses_ += static_cast<std::uint32_t>(count);
}

std::uint32_t HeadctlModel::wrap(std::int64_t steps) const {
  const auto revolution = static_cast<std::int64_t>(options_.steps_per_revolution);
  return static_cast<std::uint32_t>(((steps % revolution) + revolution) % revolution);
}

std::int64_t HeadctlModel::absolute_now() const {
  if (!motion_) return absolute_step_;
  const std::int64_t length = std::llabs(motion_->distance);
  std::int64_t travelled = std::min<std::int64_t>(length, (clock_() - motion_->start_us) * motion_->speed / 1'000'000);
  if (motion_->stall_after) travelled = std::min<std::int64_t>(travelled, *motion_->stall_after);
  return motion_->start_absolute + (motion_->distance < 0 ? -travelled : travelled);
}

std::uint32_t HeadctlModel::position_locked() const { return wrap(absolute_now() - zero_absolute_); }

TurntableStatusReply HeadctlModel::turntable_locked() const {
  TurntableStatusReply status;
  status.state = fault_ != Fault::kNone ? TurntableState::kFault
                 : motion_             ? (motion_->homing ? TurntableState::kHoming : TurntableState::kMoving)
                                       : TurntableState::kIdle;
  status.homed = homed_;
  status.fault = fault_;
  status.position_step = position_locked();
  status.target_step = target_step_;
  status.steps_per_revolution = options_.steps_per_revolution;
  status.speed_steps_per_s = speed_;
  return status;
}

}  // namespace sls::fwif::models
