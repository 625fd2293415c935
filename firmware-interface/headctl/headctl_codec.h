// The host's (and the emulated board's) codec for the head-controller protocol of
// PROTOCOL.md: frames (sync, version, flags, type, sequence, length, CRC-32) and one typed
// struct per request and reply. The wire constants come from headctl_protocol.h, the header
// the firmware compiles, so both sides share one definition.
//
// Decoding is strict: a frame or payload with any defect (short, long, bad CRC, reserved bit
// or byte not 0, a bool that is not 0/1, an enum out of range, a count over its maximum, a
// string that is not printable ASCII) throws sls::Error(kDevice) saying what was wrong, and
// never reads outside the given bytes. Encoding checks the same rules and throws
// kInvalidArgument, so every value that encodes decodes back to itself.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "firmware-interface/headctl/headctl_protocol.h"

namespace sls::fwif::headctl {

enum class MessageType : std::uint8_t {
  kIdentify = HEADCTL_MSG_IDENTIFY,
  kTriggerConfigure = HEADCTL_MSG_TRIGGER_CONFIGURE,
  kTriggerArm = HEADCTL_MSG_TRIGGER_ARM,
  kTriggerFire = HEADCTL_MSG_TRIGGER_FIRE,
  kTriggerStatus = HEADCTL_MSG_TRIGGER_STATUS,
  kTriggerDisarm = HEADCTL_MSG_TRIGGER_DISARM,
  kTurntableHome = HEADCTL_MSG_TURNTABLE_HOME,
  kTurntableMove = HEADCTL_MSG_TURNTABLE_MOVE,
  kTurntableStop = HEADCTL_MSG_TURNTABLE_STOP,
  kTurntableStatus = HEADCTL_MSG_TURNTABLE_STATUS,
  kTurntablePosition = HEADCTL_MSG_TURNTABLE_POSITION,
  kTemperatures = HEADCTL_MSG_TEMPERATURES,
  kErrorLog = HEADCTL_MSG_ERROR_LOG,
  kErrorClear = HEADCTL_MSG_ERROR_CLEAR,
};

enum class DeviceError : std::uint16_t {
  kBadFrame = HEADCTL_ERROR_BAD_FRAME,
  kUnsupportedVersion = HEADCTL_ERROR_UNSUPPORTED_VERSION,
  kUnknownMessage = HEADCTL_ERROR_UNKNOWN_MESSAGE,
  kBadPayload = HEADCTL_ERROR_BAD_PAYLOAD,
  kOutOfRange = HEADCTL_ERROR_OUT_OF_RANGE,
  kBusy = HEADCTL_ERROR_BUSY,
  kNotHomed = HEADCTL_ERROR_NOT_HOMED,
  kInvalidState = HEADCTL_ERROR_INVALID_STATE,
  kHardwareFault = HEADCTL_ERROR_HARDWARE_FAULT,
};

enum class Fault : std::uint16_t {
  kNone = HEADCTL_FAULT_NONE,
  kMotorStall = HEADCTL_FAULT_MOTOR_STALL,
  kHomeNotFound = HEADCTL_FAULT_HOME_NOT_FOUND,
  kOverTemperature = HEADCTL_FAULT_OVER_TEMPERATURE,
  kDriver = HEADCTL_FAULT_DRIVER,
};

enum class TurntableState : std::uint8_t {
  kIdle = HEADCTL_TURNTABLE_IDLE,
  kHoming = HEADCTL_TURNTABLE_HOMING,
  kMoving = HEADCTL_TURNTABLE_MOVING,
  kFault = HEADCTL_TURNTABLE_FAULT,
};

enum class Direction : std::uint8_t {
  kShortest = HEADCTL_DIRECTION_SHORTEST,
  kPositive = HEADCTL_DIRECTION_POSITIVE,
  kNegative = HEADCTL_DIRECTION_NEGATIVE,
};

enum class Polarity : std::uint8_t { kActiveHigh = HEADCTL_ACTIVE_HIGH, kActiveLow = HEADCTL_ACTIVE_LOW };

enum class TriggerSource : std::uint8_t {
  kHost = HEADCTL_TRIGGER_SOURCE_HOST,    // one pulse per TRIGGER_FIRE
  kTimer = HEADCTL_TRIGGER_SOURCE_TIMER,  // the board fires `count` pulses every `period_us`
};

// "TURNTABLE_MOVE", or "type 0x7f" for a value the protocol does not define.
std::string message_type_name(std::uint8_t type);
inline std::string message_type_name(MessageType type) { return message_type_name(static_cast<std::uint8_t>(type)); }
bool is_known_message_type(std::uint8_t type);
// True for the requests whose reply is an empty acknowledgement.
bool reply_is_acknowledge(MessageType type);
const char* device_error_name(DeviceError error);  // "NOT_HOMED"
const char* fault_name(Fault fault);                // "MOTOR_STALL"
const char* turntable_state_name(TurntableState state);

// ---- requests ---------------------------------------------------------------------------
struct IdentifyRequest {
  static constexpr MessageType kType = MessageType::kIdentify;
  bool operator==(const IdentifyRequest&) const { return true; }
};
struct TriggerConfigureRequest {
  static constexpr MessageType kType = MessageType::kTriggerConfigure;
  std::uint8_t output = 0;
  bool enabled = true;
  Polarity polarity = Polarity::kActiveHigh;
  std::uint32_t pulse_width_us = 100;
  std::uint32_t delay_us = 0;
  bool operator==(const TriggerConfigureRequest& o) const {
    return output == o.output && enabled == o.enabled && polarity == o.polarity &&
           pulse_width_us == o.pulse_width_us && delay_us == o.delay_us;
  }
};
struct TriggerArmRequest {
  static constexpr MessageType kType = MessageType::kTriggerArm;
  std::uint8_t output_mask = 1;
  TriggerSource source = TriggerSource::kHost;
  std::uint16_t count = 1;
  std::uint32_t period_us = 0;
  bool operator==(const TriggerArmRequest& o) const {
    return output_mask == o.output_mask && source == o.source && count == o.count && period_us == o.period_us;
  }
};
struct TriggerFireRequest {
  static constexpr MessageType kType = MessageType::kTriggerFire;
  bool operator==(const TriggerFireRequest&) const { return true; }
};
struct TriggerStatusRequest {
  static constexpr MessageType kType = MessageType::kTriggerStatus;
  bool operator==(const TriggerStatusRequest&) const { return true; }
};
struct TriggerDisarmRequest {
  static constexpr MessageType kType = MessageType::kTriggerDisarm;
  bool operator==(const TriggerDisarmRequest&) const { return true; }
};
struct TurntableHomeRequest {
  static constexpr MessageType kType = MessageType::kTurntableHome;
  bool operator==(const TurntableHomeRequest&) const { return true; }
};
struct TurntableMoveRequest {
  static constexpr MessageType kType = MessageType::kTurntableMove;
  std::uint32_t target_step = 0;
  Direction direction = Direction::kShortest;
  std::uint32_t speed_steps_per_s = 0;  // 0 = the board's default
  bool operator==(const TurntableMoveRequest& o) const {
    return target_step == o.target_step && direction == o.direction && speed_steps_per_s == o.speed_steps_per_s;
  }
};
struct TurntableStopRequest {
  static constexpr MessageType kType = MessageType::kTurntableStop;
  bool operator==(const TurntableStopRequest&) const { return true; }
};
struct TurntableStatusRequest {
  static constexpr MessageType kType = MessageType::kTurntableStatus;
  bool operator==(const TurntableStatusRequest&) const { return true; }
};
struct TurntablePositionRequest {
  static constexpr MessageType kType = MessageType::kTurntablePosition;
  bool operator==(const TurntablePositionRequest&) const { return true; }
};
struct TemperaturesRequest {
  static constexpr MessageType kType = MessageType::kTemperatures;
  bool operator==(const TemperaturesRequest&) const { return true; }
};
struct ErrorLogRequest {
  static constexpr MessageType kType = MessageType::kErrorLog;
  bool operator==(const ErrorLogRequest&) const { return true; }
};
struct ErrorClearRequest {
  static constexpr MessageType kType = MessageType::kErrorClear;
  bool operator==(const ErrorClearRequest&) const { return true; }
};

using Request = std::variant<IdentifyRequest, TriggerConfigureRequest, TriggerArmRequest, TriggerFireRequest,
                             TriggerStatusRequest, TriggerDisarmRequest, TurntableHomeRequest, TurntableMoveRequest,
                             TurntableStopRequest, TurntableStatusRequest, TurntablePositionRequest,
                             TemperaturesRequest, ErrorLogRequest, ErrorClearRequest>;

MessageType type_of(const Request& request);

// ---- replies ----------------------------------------------------------------------------
// The empty reply to a request that returns no data (reply_is_acknowledge(type)).
struct Acknowledge {
  MessageType type = MessageType::kTriggerConfigure;
  bool operator==(const Acknowledge& o) const { return type == o.type; }
};
struct IdentifyReply {
  std::uint8_t protocol_version = HEADCTL_PROTOCOL_VERSION;
  std::uint8_t firmware_major = 0;
  std::uint8_t firmware_minor = 0;
  std::uint8_t firmware_patch = 0;
  std::uint8_t hardware_revision = 0;
  std::uint8_t trigger_outputs = 0;      // <= HEADCTL_MAX_TRIGGER_OUTPUTS
  std::uint8_t temperature_sensors = 0;  // <= HEADCTL_MAX_TEMPERATURE_SENSORS
  std::uint32_t capabilities = 0;        // HEADCTL_CAP_*
  std::uint32_t steps_per_revolution = 0;
  std::string serial;  // printable ASCII, <= 16 characters
  std::string model;   // printable ASCII, <= 24 characters
  bool operator==(const IdentifyReply& o) const {
    return protocol_version == o.protocol_version && firmware_major == o.firmware_major &&
           firmware_minor == o.firmware_minor && firmware_patch == o.firmware_patch &&
           hardware_revision == o.hardware_revision && trigger_outputs == o.trigger_outputs &&
           temperature_sensors == o.temperature_sensors && capabilities == o.capabilities &&
           steps_per_revolution == o.steps_per_revolution && serial == o.serial && model == o.model;
  }
};
struct TriggerFireReply {
  std::uint16_t pulse_index = 0;
  std::uint16_t remaining = 0;
  std::uint64_t timestamp_us = 0;
  bool operator==(const TriggerFireReply& o) const {
    return pulse_index == o.pulse_index && remaining == o.remaining && timestamp_us == o.timestamp_us;
  }
};
struct TriggerStatusReply {
  bool armed = false;
  std::uint8_t output_mask = 0;
  std::uint16_t fired = 0;
  std::uint16_t remaining = 0;
  std::uint32_t total_pulses = 0;
  bool operator==(const TriggerStatusReply& o) const {
    return armed == o.armed && output_mask == o.output_mask && fired == o.fired && remaining == o.remaining &&
           total_pulses == o.total_pulses;
  }
};
struct TurntableStatusReply {
  TurntableState state = TurntableState::kIdle;
  bool homed = false;
  Fault fault = Fault::kNone;
  std::uint32_t position_step = 0;
  std::uint32_t target_step = 0;
  std::uint32_t steps_per_revolution = 0;
  std::uint32_t speed_steps_per_s = 0;
  bool operator==(const TurntableStatusReply& o) const {
    return state == o.state && homed == o.homed && fault == o.fault && position_step == o.position_step &&
           target_step == o.target_step && steps_per_revolution == o.steps_per_revolution &&
           speed_steps_per_s == o.speed_steps_per_s;
  }
};
struct TurntablePositionReply {
  std::uint32_t position_step = 0;
  std::uint32_t steps_per_revolution = 0;
  bool operator==(const TurntablePositionReply& o) const {
    return position_step == o.position_step && steps_per_revolution == o.steps_per_revolution;
  }
};
struct Temperature {
  std::uint8_t sensor = 0;
  std::int16_t centi_celsius = 0;
  double celsius() const { return centi_celsius / 100.0; }
  bool operator==(const Temperature& o) const { return sensor == o.sensor && centi_celsius == o.centi_celsius; }
};
struct TemperaturesReply {
  std::vector<Temperature> sensors;  // <= HEADCTL_MAX_TEMPERATURE_SENSORS
  bool operator==(const TemperaturesReply& o) const { return sensors == o.sensors; }
};
struct ErrorLogEntry {
  DeviceError code = DeviceError::kBadFrame;
  std::uint8_t type = 0;  // raw: the refused request may have had an unknown type
  std::uint8_t sequence = 0;
  std::uint32_t detail = 0;
  std::uint32_t timestamp_ms = 0;
  bool operator==(const ErrorLogEntry& o) const {
    return code == o.code && type == o.type && sequence == o.sequence && detail == o.detail &&
           timestamp_ms == o.timestamp_ms;
  }
};
struct ErrorLogReply {
  std::vector<ErrorLogEntry> entries;  // oldest first, <= HEADCTL_MAX_ERROR_LOG_ENTRIES
  bool operator==(const ErrorLogReply& o) const { return entries == o.entries; }
};
// The board refused a request (HEADCTL_FLAG_ERROR).
struct ErrorReply {
  std::uint8_t type = 0;  // raw: echoes the request's type, known or not
  DeviceError code = DeviceError::kBadFrame;
  std::uint32_t detail = 0;
  std::string text;  // printable ASCII, <= HEADCTL_MAX_ERROR_TEXT
  bool operator==(const ErrorReply& o) const {
    return type == o.type && code == o.code && detail == o.detail && text == o.text;
  }
};

using Reply = std::variant<Acknowledge, IdentifyReply, TriggerFireReply, TriggerStatusReply, TurntableStatusReply,
                           TurntablePositionReply, TemperaturesReply, ErrorLogReply, ErrorReply>;

// The type byte a reply is sent with.
std::uint8_t reply_type(const Reply& reply);

// ---- frames -----------------------------------------------------------------------------
struct Frame {
  std::uint8_t flags = 0;
  std::uint8_t type = 0;
  std::uint8_t sequence = 0;
  std::vector<std::uint8_t> payload;
  bool is_reply() const { return (flags & HEADCTL_FLAG_REPLY) != 0; }
  bool is_error() const { return (flags & HEADCTL_FLAG_ERROR) != 0; }
  bool operator==(const Frame& o) const {
    return flags == o.flags && type == o.type && sequence == o.sequence && payload == o.payload;
  }
};

// Frame bytes: header, payload, CRC. Throws kInvalidArgument for reserved flags or a payload
// over HEADCTL_MAX_PAYLOAD.
std::vector<std::uint8_t> encode_frame(const Frame& frame);
// Exactly one frame of the current protocol version. Throws kDevice (bad sync, version,
// reserved flags, length, CRC, trailing bytes) and kVersionMismatch for another version.
Frame decode_frame(const std::uint8_t* data, std::size_t size);

// The sequence byte of bytes that start like a frame (sync and enough header), so a board
// can address its BAD_FRAME error to the request it could not read; false otherwise.
bool peek_sequence(const std::uint8_t* data, std::size_t size, std::uint8_t* sequence);

std::vector<std::uint8_t> encode_request(std::uint8_t sequence, const Request& request);
std::vector<std::uint8_t> encode_reply(std::uint8_t sequence, const Reply& reply);
// The typed request of a host-to-board frame; kDevice for a reply frame, an unknown type
// (check is_known_message_type first to answer UNKNOWN_MESSAGE) or a bad payload.
Request decode_request(const Frame& frame);
// The typed reply of a board-to-host frame; kDevice when it is not a reply or is malformed.
Reply decode_reply(const Frame& frame);

}  // namespace sls::fwif::headctl
