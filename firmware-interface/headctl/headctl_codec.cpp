#include "firmware-interface/headctl/headctl_codec.h"

#include <fmt/format.h>

#include <type_traits>

#include "firmware-interface/wire_bytes.h"
#include "sdk/core/error.h"

namespace sls::fwif::headctl {
namespace {

template <typename T>
constexpr std::underlying_type_t<T> raw(T value) {
  return static_cast<std::underlying_type_t<T>>(value);
}

std::string context(std::uint8_t type, const char* what) { return fmt::format("headctl {} {}", message_type_name(type), what); }

// ---- enum reading/checking ----
Polarity read_polarity(ByteReader& in) {
  const std::uint8_t value = in.u8("polarity");
  if (value > HEADCTL_ACTIVE_LOW) throw_error(ErrorCode::kDevice, "{}: polarity {} out of range", in.context(), value);
  return static_cast<Polarity>(value);
}
TriggerSource read_trigger_source(ByteReader& in) {
  const std::uint8_t value = in.u8("source");
  if (value > HEADCTL_TRIGGER_SOURCE_TIMER) throw_error(ErrorCode::kDevice, "{}: source {} out of range", in.context(), value);
  return static_cast<TriggerSource>(value);
}
Direction read_direction(ByteReader& in) {
  const std::uint8_t value = in.u8("direction");
  if (value > HEADCTL_DIRECTION_NEGATIVE) throw_error(ErrorCode::kDevice, "{}: direction {} out of range", in.context(), value);
  return static_cast<Direction>(value);
}
TurntableState read_turntable_state(ByteReader& in) {
  const std::uint8_t value = in.u8("state");
  if (value > HEADCTL_TURNTABLE_FAULT) throw_error(ErrorCode::kDevice, "{}: turntable state {} out of range", in.context(), value);
  return static_cast<TurntableState>(value);
}
Fault read_fault(ByteReader& in) {
  const std::uint16_t value = in.u16("fault");
  if (value > HEADCTL_FAULT_DRIVER) throw_error(ErrorCode::kDevice, "{}: fault {} out of range", in.context(), value);
  return static_cast<Fault>(value);
}
DeviceError read_device_error(ByteReader& in) {
  const std::uint16_t value = in.u16("error code");
  if (value < HEADCTL_ERROR_BAD_FRAME || value > HEADCTL_ERROR_HARDWARE_FAULT) {
    throw_error(ErrorCode::kDevice, "{}: error code {} out of range", in.context(), value);
  }
  return static_cast<DeviceError>(value);
}

void check_enum(bool in_range, const char* what, unsigned value) {
  if (!in_range) throw_error(ErrorCode::kInvalidArgument, "headctl encode: {} {} out of range", what, value);
}
void check_text(const std::string& text, std::size_t max_size, const char* what) {
  if (text.size() > max_size || !is_printable_ascii(text)) {
    throw_error(ErrorCode::kInvalidArgument, "headctl encode: {} '{}' must be printable ASCII of at most {} characters",
                what, text, max_size);
  }
}

// ---- request payloads ----
void write_payload(ByteWriter&, const IdentifyRequest&) {}
void write_payload(ByteWriter& out, const TriggerConfigureRequest& r) {
  check_enum(raw(r.polarity) <= HEADCTL_ACTIVE_LOW, "polarity", raw(r.polarity));
  out.u8(r.output);
  out.u8(r.enabled ? 1 : 0);
  out.u8(raw(r.polarity));
  out.zeros(1);
  out.u32(r.pulse_width_us);
  out.u32(r.delay_us);
}
void write_payload(ByteWriter& out, const TriggerArmRequest& r) {
  check_enum(raw(r.source) <= HEADCTL_TRIGGER_SOURCE_TIMER, "trigger source", raw(r.source));
  out.u8(r.output_mask);
  out.u8(raw(r.source));
  out.u16(r.count);
  out.u32(r.period_us);
}
void write_payload(ByteWriter&, const TriggerFireRequest&) {}
void write_payload(ByteWriter&, const TriggerStatusRequest&) {}
void write_payload(ByteWriter&, const TriggerDisarmRequest&) {}
void write_payload(ByteWriter&, const TurntableHomeRequest&) {}
void write_payload(ByteWriter& out, const TurntableMoveRequest& r) {
  check_enum(raw(r.direction) <= HEADCTL_DIRECTION_NEGATIVE, "direction", raw(r.direction));
  out.u32(r.target_step);
  out.u8(raw(r.direction));
  out.zeros(3);
  out.u32(r.speed_steps_per_s);
}
void write_payload(ByteWriter&, const TurntableStopRequest&) {}
void write_payload(ByteWriter&, const TurntableStatusRequest&) {}
void write_payload(ByteWriter&, const TurntablePositionRequest&) {}
void write_payload(ByteWriter&, const TemperaturesRequest&) {}
void write_payload(ByteWriter&, const ErrorLogRequest&) {}
void write_payload(ByteWriter&, const ErrorClearRequest&) {}

Request read_request(MessageType type, ByteReader& in) {
  switch (type) {
    case MessageType::kIdentify: return IdentifyRequest{};
    case MessageType::kTriggerConfigure: {
      TriggerConfigureRequest r;
      r.output = in.u8("output");
      r.enabled = in.flag("enabled");
      r.polarity = read_polarity(in);
      in.reserved(1, "reserved");
      r.pulse_width_us = in.u32("pulse_width_us");
      r.delay_us = in.u32("delay_us");
      return r;
    }
    case MessageType::kTriggerArm: {
      TriggerArmRequest r;
      r.output_mask = in.u8("output_mask");
      r.source = read_trigger_source(in);
      r.count = in.u16("count");
      r.period_us = in.u32("period_us");
      return r;
    }
    case MessageType::kTriggerFire: return TriggerFireRequest{};
    case MessageType::kTriggerStatus: return TriggerStatusRequest{};
    case MessageType::kTriggerDisarm: return TriggerDisarmRequest{};
    case MessageType::kTurntableHome: return TurntableHomeRequest{};
    case MessageType::kTurntableMove: {
      TurntableMoveRequest r;
      r.target_step = in.u32("target_step");
      r.direction = read_direction(in);
      in.reserved(3, "reserved");
      r.speed_steps_per_s = in.u32("speed");
      return r;
    }
    case MessageType::kTurntableStop: return TurntableStopRequest{};
    case MessageType::kTurntableStatus: return TurntableStatusRequest{};
    case MessageType::kTurntablePosition: return TurntablePositionRequest{};
    case MessageType::kTemperatures: return TemperaturesRequest{};
    case MessageType::kErrorLog: return ErrorLogRequest{};
    case MessageType::kErrorClear: return ErrorClearRequest{};
  }
  throw_error(ErrorCode::kDevice, "{}: unknown message type", in.context());
}

// ---- reply payloads ----
void write_payload(ByteWriter&, const Acknowledge&) {}
void write_payload(ByteWriter& out, const IdentifyReply& r) {
  check_enum(r.trigger_outputs <= HEADCTL_MAX_TRIGGER_OUTPUTS, "trigger_outputs", r.trigger_outputs);
  check_enum(r.temperature_sensors <= HEADCTL_MAX_TEMPERATURE_SENSORS, "temperature_sensors", r.temperature_sensors);
  check_text(r.serial, HEADCTL_SERIAL_SIZE, "serial");
  check_text(r.model, HEADCTL_MODEL_SIZE, "model");
  out.u8(r.protocol_version);
  out.u8(r.firmware_major);
  out.u8(r.firmware_minor);
  out.u8(r.firmware_patch);
  out.u8(r.hardware_revision);
  out.u8(r.trigger_outputs);
  out.u8(r.temperature_sensors);
  out.zeros(1);
  out.u32(r.capabilities);
  out.u32(r.steps_per_revolution);
  out.padded_text(r.serial, HEADCTL_SERIAL_SIZE);
  out.padded_text(r.model, HEADCTL_MODEL_SIZE);
}
void write_payload(ByteWriter& out, const TriggerFireReply& r) {
  out.u16(r.pulse_index);
  out.u16(r.remaining);
  out.zeros(4);
  out.u64(r.timestamp_us);
}
void write_payload(ByteWriter& out, const TriggerStatusReply& r) {
  out.u8(r.armed ? 1 : 0);
  out.u8(r.output_mask);
  out.u16(r.fired);
  out.u16(r.remaining);
  out.zeros(2);
  out.u32(r.total_pulses);
}
void write_payload(ByteWriter& out, const TurntableStatusReply& r) {
  check_enum(raw(r.state) <= HEADCTL_TURNTABLE_FAULT, "turntable state", raw(r.state));
  check_enum(raw(r.fault) <= HEADCTL_FAULT_DRIVER, "fault", raw(r.fault));
  out.u8(raw(r.state));
  out.u8(r.homed ? 1 : 0);
  out.u16(raw(r.fault));
  out.u32(r.position_step);
  out.u32(r.target_step);
  out.u32(r.steps_per_revolution);
  out.u32(r.speed_steps_per_s);
}
void write_payload(ByteWriter& out, const TurntablePositionReply& r) {
  out.u32(r.position_step);
  out.u32(r.steps_per_revolution);
}
void write_payload(ByteWriter& out, const TemperaturesReply& r) {
  check_enum(r.sensors.size() <= HEADCTL_MAX_TEMPERATURE_SENSORS, "temperature count",
             static_cast<unsigned>(r.sensors.size()));
  out.u8(static_cast<std::uint8_t>(r.sensors.size()));
  for (const Temperature& t : r.sensors) {
    out.u8(t.sensor);
    out.zeros(1);
    out.i16(t.centi_celsius);
  }
}
void check_device_error(DeviceError code) {
  check_enum(raw(code) >= HEADCTL_ERROR_BAD_FRAME && raw(code) <= HEADCTL_ERROR_HARDWARE_FAULT, "error code", raw(code));
}
void write_payload(ByteWriter& out, const ErrorLogReply& r) {
  check_enum(r.entries.size() <= HEADCTL_MAX_ERROR_LOG_ENTRIES, "error log count",
             static_cast<unsigned>(r.entries.size()));
  out.u8(static_cast<std::uint8_t>(r.entries.size()));
  for (const ErrorLogEntry& e : r.entries) {
    check_device_error(e.code);
    out.u16(raw(e.code));
    out.u8(e.type);
    out.u8(e.sequence);
    out.u32(e.detail);
    out.u32(e.timestamp_ms);
  }
}
void write_payload(ByteWriter& out, const ErrorReply& r) {
  check_device_error(r.code);
  check_text(r.text, HEADCTL_MAX_ERROR_TEXT, "error text");
  out.u16(raw(r.code));
  out.u32(r.detail);
  out.u8(static_cast<std::uint8_t>(r.text.size()));
  out.padded_text(r.text, r.text.size());
}

Reply read_reply(std::uint8_t type_byte, ByteReader& in) {
  const auto type = static_cast<MessageType>(type_byte);
  if (reply_is_acknowledge(type)) return Acknowledge{type};
  switch (type) {
    case MessageType::kIdentify: {
      IdentifyReply r;
      r.protocol_version = in.u8("protocol_version");
      r.firmware_major = in.u8("firmware_major");
      r.firmware_minor = in.u8("firmware_minor");
      r.firmware_patch = in.u8("firmware_patch");
      r.hardware_revision = in.u8("hardware_revision");
      r.trigger_outputs = in.u8("trigger_outputs");
      if (r.trigger_outputs > HEADCTL_MAX_TRIGGER_OUTPUTS) {
        throw_error(ErrorCode::kDevice, "{}: {} trigger outputs, more than {}", in.context(), r.trigger_outputs,
                    HEADCTL_MAX_TRIGGER_OUTPUTS);
      }
      r.temperature_sensors = in.u8("temperature_sensors");
      if (r.temperature_sensors > HEADCTL_MAX_TEMPERATURE_SENSORS) {
        throw_error(ErrorCode::kDevice, "{}: {} temperature sensors, more than {}", in.context(),
                    r.temperature_sensors, HEADCTL_MAX_TEMPERATURE_SENSORS);
      }
      in.reserved(1, "reserved");
      r.capabilities = in.u32("capabilities");
      r.steps_per_revolution = in.u32("steps_per_revolution");
      r.serial = in.padded_text(HEADCTL_SERIAL_SIZE, "serial");
      r.model = in.padded_text(HEADCTL_MODEL_SIZE, "model");
      return r;
    }
    case MessageType::kTriggerFire: {
      TriggerFireReply r;
      r.pulse_index = in.u16("pulse_index");
      r.remaining = in.u16("remaining");
      in.reserved(4, "reserved");
      r.timestamp_us = in.u64("timestamp_us");
      return r;
    }
    case MessageType::kTriggerStatus: {
      TriggerStatusReply r;
      r.armed = in.flag("armed");
      r.output_mask = in.u8("output_mask");
      r.fired = in.u16("fired");
      r.remaining = in.u16("remaining");
      in.reserved(2, "reserved");
      r.total_pulses = in.u32("total_pulses");
      return r;
    }
    case MessageType::kTurntableStatus: {
      TurntableStatusReply r;
      r.state = read_turntable_state(in);
      r.homed = in.flag("homed");
      r.fault = read_fault(in);
      r.position_step = in.u32("position_step");
      r.target_step = in.u32("target_step");
      r.steps_per_revolution = in.u32("steps_per_revolution");
      r.speed_steps_per_s = in.u32("speed");
      return r;
    }
    case MessageType::kTurntablePosition: {
      TurntablePositionReply r;
      r.position_step = in.u32("position_step");
      r.steps_per_revolution = in.u32("steps_per_revolution");
      return r;
    }
    case MessageType::kTemperatures: {
      TemperaturesReply r;
      const std::uint8_t count = in.u8("count");
      if (count > HEADCTL_MAX_TEMPERATURE_SENSORS) {
        throw_error(ErrorCode::kDevice, "{}: {} sensors, more than {}", in.context(), count,
                    HEADCTL_MAX_TEMPERATURE_SENSORS);
      }
      for (std::uint8_t i = 0; i < count; ++i) {
        Temperature t;
        t.sensor = in.u8("sensor");
        in.reserved(1, "sensor reserved");
        t.centi_celsius = in.i16("centi_celsius");
        r.sensors.push_back(t);
      }
      return r;
    }
    case MessageType::kErrorLog: {
      ErrorLogReply r;
      const std::uint8_t count = in.u8("count");
      if (count > HEADCTL_MAX_ERROR_LOG_ENTRIES) {
        throw_error(ErrorCode::kDevice, "{}: {} entries, more than {}", in.context(), count,
                    HEADCTL_MAX_ERROR_LOG_ENTRIES);
      }
      for (std::uint8_t i = 0; i < count; ++i) {
        ErrorLogEntry e;
        e.code = read_device_error(in);
        e.type = in.u8("type");
        e.sequence = in.u8("sequence");
        e.detail = in.u32("detail");
        e.timestamp_ms = in.u32("timestamp_ms");
        r.entries.push_back(e);
      }
      return r;
    }
    default:
      break;
  }
  throw_error(ErrorCode::kDevice, "{}: not a reply the protocol defines", in.context());
}

}  // namespace

std::string message_type_name(std::uint8_t type) {
  switch (static_cast<MessageType>(type)) {
    case MessageType::kIdentify: return "IDENTIFY";
    case MessageType::kTriggerConfigure: return "TRIGGER_CONFIGURE";
    case MessageType::kTriggerArm: return "TRIGGER_ARM";
    case MessageType::kTriggerFire: return "TRIGGER_FIRE";
    case MessageType::kTriggerStatus: return "TRIGGER_STATUS";
    case MessageType::kTriggerDisarm: return "TRIGGER_DISARM";
    case MessageType::kTurntableHome: return "TURNTABLE_HOME";
    case MessageType::kTurntableMove: return "TURNTABLE_MOVE";
    case MessageType::kTurntableStop: return "TURNTABLE_STOP";
    case MessageType::kTurntableStatus: return "TURNTABLE_STATUS";
    case MessageType::kTurntablePosition: return "TURNTABLE_POSITION";
    case MessageType::kTemperatures: return "TEMPERATURES";
    case MessageType::kErrorLog: return "ERROR_LOG";
    case MessageType::kErrorClear: return "ERROR_CLEAR";
  }
  return fmt::format("type 0x{:02x}", type);
}

bool is_known_message_type(std::uint8_t type) { return message_type_name(type).rfind("type 0x", 0) != 0; }

bool reply_is_acknowledge(MessageType type) {
  switch (type) {
    case MessageType::kTriggerConfigure:
    case MessageType::kTriggerArm:
    case MessageType::kTriggerDisarm:
    case MessageType::kTurntableHome:
    case MessageType::kTurntableMove:
    case MessageType::kTurntableStop:
    case MessageType::kErrorClear:
      return true;
    default:
      return false;
  }
}

const char* device_error_name(DeviceError error) {
  switch (error) {
    case DeviceError::kBadFrame: return "BAD_FRAME";
    case DeviceError::kUnsupportedVersion: return "UNSUPPORTED_VERSION";
    case DeviceError::kUnknownMessage: return "UNKNOWN_MESSAGE";
    case DeviceError::kBadPayload: return "BAD_PAYLOAD";
    case DeviceError::kOutOfRange: return "OUT_OF_RANGE";
    case DeviceError::kBusy: return "BUSY";
    case DeviceError::kNotHomed: return "NOT_HOMED";
    case DeviceError::kInvalidState: return "INVALID_STATE";
    case DeviceError::kHardwareFault: return "HARDWARE_FAULT";
  }
  return "unknown error";
}

const char* fault_name(Fault fault) {
  switch (fault) {
    case Fault::kNone: return "NONE";
    case Fault::kMotorStall: return "MOTOR_STALL";
    case Fault::kHomeNotFound: return "HOME_NOT_FOUND";
    case Fault::kOverTemperature: return "OVER_TEMPERATURE";
    case Fault::kDriver: return "DRIVER";
  }
  return "unknown fault";
}

const char* turntable_state_name(TurntableState state) {
  switch (state) {
    case TurntableState::kIdle: return "IDLE";
    case TurntableState::kHoming: return "HOMING";
    case TurntableState::kMoving: return "MOVING";
    case TurntableState::kFault: return "FAULT";
  }
  return "unknown state";
}

MessageType type_of(const Request& request) {
  return std::visit([](const auto& r) { return std::decay_t<decltype(r)>::kType; }, request);
}

std::uint8_t reply_type(const Reply& reply) {
  return std::visit(
      [](const auto& r) -> std::uint8_t {
        using T = std::decay_t<decltype(r)>;
        if constexpr (std::is_same_v<T, Acknowledge>) return raw(r.type);
        else if constexpr (std::is_same_v<T, ErrorReply>) return r.type;
        else if constexpr (std::is_same_v<T, IdentifyReply>) return HEADCTL_MSG_IDENTIFY;
        else if constexpr (std::is_same_v<T, TriggerFireReply>) return HEADCTL_MSG_TRIGGER_FIRE;
        else if constexpr (std::is_same_v<T, TriggerStatusReply>) return HEADCTL_MSG_TRIGGER_STATUS;
        else if constexpr (std::is_same_v<T, TurntableStatusReply>) return HEADCTL_MSG_TURNTABLE_STATUS;
        else if constexpr (std::is_same_v<T, TurntablePositionReply>) return HEADCTL_MSG_TURNTABLE_POSITION;
        else if constexpr (std::is_same_v<T, TemperaturesReply>) return HEADCTL_MSG_TEMPERATURES;
        else return HEADCTL_MSG_ERROR_LOG;
      },
      reply);
}

std::vector<std::uint8_t> encode_frame(const Frame& frame) {
  if ((frame.flags & HEADCTL_FLAGS_RESERVED) != 0) {
    throw_error(ErrorCode::kInvalidArgument, "headctl encode: reserved flag bits 0x{:02x} set", frame.flags);
  }
  if (frame.payload.size() > HEADCTL_MAX_PAYLOAD) {
    throw_error(ErrorCode::kInvalidArgument, "headctl encode: {} payload of {} bytes exceeds {}",
                message_type_name(frame.type), frame.payload.size(), HEADCTL_MAX_PAYLOAD);
  }
  std::vector<std::uint8_t> bytes;
  bytes.reserve(HEADCTL_FRAME_HEADER_SIZE + frame.payload.size() + HEADCTL_FRAME_CRC_SIZE);
  ByteWriter out(bytes);
  out.u8(HEADCTL_SYNC0);
  out.u8(HEADCTL_SYNC1);
  out.u8(HEADCTL_PROTOCOL_VERSION);
  out.u8(frame.flags);
  out.u8(frame.type);
  out.u8(frame.sequence);
  out.u16(static_cast<std::uint16_t>(frame.payload.size()));
  out.bytes(frame.payload.data(), frame.payload.size());
  out.u32(headctl_crc32(0, bytes.data() + HEADCTL_FRAME_OFF_VERSION, bytes.size() - HEADCTL_FRAME_OFF_VERSION));
  return bytes;
}

Frame decode_frame(const std::uint8_t* data, std::size_t size) {
  ByteReader in(data, size, "headctl frame");
  const std::uint8_t sync0 = in.u8("sync");
  const std::uint8_t sync1 = in.u8("sync");
  if (sync0 != HEADCTL_SYNC0 || sync1 != HEADCTL_SYNC1) {
    throw_error(ErrorCode::kDevice, "headctl frame: sync bytes {:02x} {:02x}, expected a5 5a", sync0, sync1);
  }
  const std::uint8_t version = in.u8("version");
  if (version != HEADCTL_PROTOCOL_VERSION) {
    throw_error(ErrorCode::kVersionMismatch, "headctl frame: protocol version {}, this host speaks {}", version,
                HEADCTL_PROTOCOL_VERSION);
  }
  Frame frame;
  frame.flags = in.u8("flags");
  if ((frame.flags & HEADCTL_FLAGS_RESERVED) != 0) {
    throw_error(ErrorCode::kDevice, "headctl frame: reserved flag bits set (flags 0x{:02x})", frame.flags);
  }
  frame.type = in.u8("type");
  frame.sequence = in.u8("sequence");
  const std::uint16_t length = in.u16("length");
  if (length > HEADCTL_MAX_PAYLOAD) {
    throw_error(ErrorCode::kDevice, "headctl frame: payload length {} exceeds {}", length, HEADCTL_MAX_PAYLOAD);
  }
  if (in.remaining() != std::size_t{length} + HEADCTL_FRAME_CRC_SIZE) {
    throw_error(ErrorCode::kDevice, "headctl frame: {} bytes after the header, the length field says {} + {} CRC",
                in.remaining(), length, HEADCTL_FRAME_CRC_SIZE);
  }
  const std::uint32_t computed = headctl_crc32(0, data + HEADCTL_FRAME_OFF_VERSION,
                                               HEADCTL_FRAME_HEADER_SIZE - HEADCTL_FRAME_OFF_VERSION + length);
  frame.payload.assign(data + HEADCTL_FRAME_HEADER_SIZE, data + HEADCTL_FRAME_HEADER_SIZE + length);
  ByteReader crc_in(data + HEADCTL_FRAME_HEADER_SIZE + length, HEADCTL_FRAME_CRC_SIZE, "headctl frame");
  const std::uint32_t received = crc_in.u32("crc");
  if (received != computed) {
    throw_error(ErrorCode::kDevice, "headctl frame: {} seq {} CRC 0x{:08x} does not match the computed 0x{:08x}",
                message_type_name(frame.type), frame.sequence, received, computed);
  }
  return frame;
}

bool peek_sequence(const std::uint8_t* data, std::size_t size, std::uint8_t* sequence) {
  if (size < HEADCTL_FRAME_HEADER_SIZE || data[0] != HEADCTL_SYNC0 || data[1] != HEADCTL_SYNC1) return false;
  *sequence = data[HEADCTL_FRAME_OFF_SEQUENCE];
  return true;
}

std::vector<std::uint8_t> encode_request(std::uint8_t sequence, const Request& request) {
  Frame frame;
  frame.type = raw(type_of(request));
  frame.sequence = sequence;
  ByteWriter out(frame.payload);
  std::visit([&out](const auto& r) { write_payload(out, r); }, request);
  return encode_frame(frame);
}

std::vector<std::uint8_t> encode_reply(std::uint8_t sequence, const Reply& reply) {
  Frame frame;
  frame.flags = HEADCTL_FLAG_REPLY;
  if (std::holds_alternative<ErrorReply>(reply)) frame.flags |= HEADCTL_FLAG_ERROR;
  if (const auto* ack = std::get_if<Acknowledge>(&reply); ack != nullptr && !reply_is_acknowledge(ack->type)) {
    throw_error(ErrorCode::kInvalidArgument, "headctl encode: {} has a reply with data, not an acknowledgement",
                message_type_name(ack->type));
  }
  frame.type = reply_type(reply);
  frame.sequence = sequence;
  ByteWriter out(frame.payload);
  std::visit([&out](const auto& r) { write_payload(out, r); }, reply);
  return encode_frame(frame);
}

Request decode_request(const Frame& frame) {
  const std::string what = context(frame.type, "request");
  if (frame.is_reply() || frame.is_error()) {
    throw_error(ErrorCode::kDevice, "{}: flags 0x{:02x} mark a reply", what, frame.flags);
  }
  if (!is_known_message_type(frame.type)) throw_error(ErrorCode::kDevice, "{}: unknown message type", what);
  ByteReader in(frame.payload.data(), frame.payload.size(), what);
  Request request = read_request(static_cast<MessageType>(frame.type), in);
  in.expect_end();
  return request;
}

Reply decode_reply(const Frame& frame) {
  if (!frame.is_reply()) {
    throw_error(ErrorCode::kDevice, "{}: flags 0x{:02x} lack the reply bit", context(frame.type, "reply"), frame.flags);
  }
  if (frame.is_error()) {
    ByteReader in(frame.payload.data(), frame.payload.size(), context(frame.type, "error reply"));
    ErrorReply r;
    r.type = frame.type;
    r.code = read_device_error(in);
    r.detail = in.u32("detail");
    const std::uint8_t text_length = in.u8("text_length");
    if (text_length > HEADCTL_MAX_ERROR_TEXT) {
      throw_error(ErrorCode::kDevice, "{}: text of {} bytes exceeds {}", in.context(), text_length,
                  HEADCTL_MAX_ERROR_TEXT);
    }
    r.text = in.text(text_length, "text");
    in.expect_end();
    return r;
  }
  const std::string what = context(frame.type, "reply");
  if (!is_known_message_type(frame.type)) throw_error(ErrorCode::kDevice, "{}: unknown message type", what);
  ByteReader in(frame.payload.data(), frame.payload.size(), what);
  Reply reply = read_reply(frame.type, in);
  in.expect_end();
  return reply;
}

}  // namespace sls::fwif::headctl
