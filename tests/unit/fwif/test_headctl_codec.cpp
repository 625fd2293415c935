// The head-controller protocol codec: CRC, framing, every message round-tripped, and strict
// rejection of anything malformed; plus the C99 header used the way firmware uses it.
#include <gtest/gtest.h>

#include <cstring>
#include <set>
#include <string>
#include <vector>

#include "firmware-interface/headctl/headctl_codec.h"
#include "sdk/core/error.h"

extern "C" {
std::uint32_t headctl_c_check_value(void);
std::size_t headctl_c_build_frame(std::uint8_t* out, std::uint8_t flags, std::uint8_t type, std::uint8_t sequence,
                                  const std::uint8_t* payload, std::uint16_t length);
std::size_t headctl_c_move_request(std::uint8_t* out, std::uint8_t sequence, std::uint32_t target_step,
                                   std::uint8_t direction, std::uint32_t speed);
int headctl_c_read_turntable_status(const std::uint8_t* frame, std::size_t size, headctl_turntable_status* status);
}

namespace sls::fwif::headctl {
namespace {

std::vector<Request> request_samples() {
  return {IdentifyRequest{},
          TriggerConfigureRequest{3, false, Polarity::kActiveLow, 1'000'000, 250},
          TriggerConfigureRequest{0, true, Polarity::kActiveHigh, 1, 0},
          TriggerArmRequest{0x0F, TriggerSource::kTimer, 65535, 8333},
          TriggerArmRequest{0x01, TriggerSource::kHost, 1, 0},
          TriggerFireRequest{},
          TriggerStatusRequest{},
          TriggerDisarmRequest{},
          TurntableHomeRequest{},
          TurntableMoveRequest{6399, Direction::kNegative, 0xFFFFFFFFu},
          TurntableMoveRequest{0, Direction::kShortest, 0},
          TurntableMoveRequest{1600, Direction::kPositive, 3200},
          TurntableStopRequest{},
          TurntableStatusRequest{},
          TurntablePositionRequest{},
          TemperaturesRequest{},
          ErrorLogRequest{},
          ErrorClearRequest{}};
}

std::vector<Reply> reply_samples() {
  std::vector<Reply> replies;
  for (const MessageType type : {MessageType::kTriggerConfigure, MessageType::kTriggerArm, MessageType::kTriggerDisarm,
                                 MessageType::kTurntableHome, MessageType::kTurntableMove, MessageType::kTurntableStop,
                                 MessageType::kErrorClear}) {
    replies.push_back(Acknowledge{type});
  }
  IdentifyReply id;
  id.firmware_major = 1;
  id.firmware_minor = 2;
  id.firmware_patch = 255;
  id.hardware_revision = 7;
  id.trigger_outputs = HEADCTL_MAX_TRIGGER_OUTPUTS;
  id.temperature_sensors = 2;
  id.capabilities = HEADCTL_CAP_TRIGGERS | HEADCTL_CAP_TURNTABLE | HEADCTL_CAP_TEMPERATURES;
  id.steps_per_revolution = 51200;
  id.serial = "SN-0123456789ABC";                  // 16 characters: the whole field
  id.model = "OEM head controller r2 ~";            // 24 characters
  replies.push_back(id);
  replies.push_back(IdentifyReply{});               // empty strings
  replies.push_back(TriggerFireReply{65535, 0, 0xFFFFFFFFFFFFFFFFull});
  replies.push_back(TriggerStatusReply{true, 0x81, 3, 4, 0xFFFFFFFFu});
  replies.push_back(TriggerStatusReply{});
  for (const auto state : {TurntableState::kIdle, TurntableState::kHoming, TurntableState::kMoving, TurntableState::kFault}) {
    replies.push_back(TurntableStatusReply{state, state == TurntableState::kIdle, Fault::kNone, 17, 1600, 6400, 3200});
  }
  for (const auto fault : {Fault::kMotorStall, Fault::kHomeNotFound, Fault::kOverTemperature, Fault::kDriver}) {
    replies.push_back(TurntableStatusReply{TurntableState::kFault, false, fault, 0, 0, 6400, 0});
  }
  replies.push_back(TurntablePositionReply{6399, 6400});
  replies.push_back(TemperaturesReply{});
  TemperaturesReply full;
  for (std::uint8_t i = 0; i < HEADCTL_MAX_TEMPERATURE_SENSORS; ++i) {
    full.sensors.push_back({i, static_cast<std::int16_t>(i % 2 == 0 ? -4000 + i : 12000 - i)});
  }
  replies.push_back(full);
  replies.push_back(ErrorLogReply{});
  ErrorLogReply log;
  for (std::uint8_t i = 0; i < HEADCTL_MAX_ERROR_LOG_ENTRIES; ++i) {
    log.entries.push_back({static_cast<DeviceError>(1 + i % 9), static_cast<std::uint8_t>(0x20 + i), i,
                           0xFFFFFFF0u + i, 1000u * i});
  }
  replies.push_back(log);
  for (std::uint16_t code = HEADCTL_ERROR_BAD_FRAME; code <= HEADCTL_ERROR_HARDWARE_FAULT; ++code) {
    replies.push_back(ErrorReply{HEADCTL_MSG_TURNTABLE_MOVE, static_cast<DeviceError>(code), code * 1000u, "refused"});
  }
  replies.push_back(ErrorReply{0x7F, DeviceError::kUnknownMessage, 0x7F, std::string(HEADCTL_MAX_ERROR_TEXT, 'x')});
  replies.push_back(ErrorReply{HEADCTL_MSG_IDENTIFY, DeviceError::kBadFrame, 0, ""});
  return replies;
}

TEST(HeadctlCrc, MatchesTheCrc32CheckValue) {
  const std::uint8_t digits[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(headctl_crc32(0, digits, sizeof digits), 0xCBF43926u);
  EXPECT_EQ(headctl_crc32(0, nullptr, 0), 0u);
  // Chained calls give the CRC of the concatenation.
  EXPECT_EQ(headctl_crc32(headctl_crc32(0, digits, 4), digits + 4, 5), 0xCBF43926u);
  EXPECT_EQ(headctl_c_check_value(), 0xCBF43926u);  // the same function compiled as C99
}

TEST(HeadctlFrame, ExampleFramesAreThoseOfProtocolMd) {
  // PROTOCOL.md, "Examples": TURNTABLE_MOVE to step 1600, positive, 3200 steps/s, sequence 42.
  const std::vector<std::uint8_t> move = {0xA5, 0x5A, 0x01, 0x00, 0x21, 0x2A, 0x0C, 0x00, 0x40, 0x06, 0x00, 0x00,
                                          0x01, 0x00, 0x00, 0x00, 0x80, 0x0C, 0x00, 0x00, 0x97, 0x73, 0x1E, 0x04};
  EXPECT_EQ(encode_request(42, TurntableMoveRequest{1600, Direction::kPositive, 3200}), move);
  // IDENTIFY, sequence 1.
  const std::vector<std::uint8_t> expected = {0xA5, 0x5A, 0x01, 0x00, 0x01, 0x01, 0x00, 0x00, 0x54, 0x7F, 0xE0, 0xC3};
  EXPECT_EQ(encode_request(1, IdentifyRequest{}), expected);
  std::uint8_t from_c[HEADCTL_MAX_FRAME_SIZE];
  const std::size_t size = headctl_c_build_frame(from_c, 0, HEADCTL_MSG_IDENTIFY, 1, nullptr, 0);
  EXPECT_EQ(std::vector<std::uint8_t>(from_c, from_c + size), expected);
}

TEST(HeadctlFrame, FirmwareWrittenInCAgreesWithTheHostCodec) {
  std::uint8_t move[HEADCTL_MAX_FRAME_SIZE];
  const std::size_t size = headctl_c_move_request(move, 42, 1600, HEADCTL_DIRECTION_POSITIVE, 3200);
  EXPECT_EQ(std::vector<std::uint8_t>(move, move + size),
            encode_request(42, TurntableMoveRequest{1600, Direction::kPositive, 3200}));

  const TurntableStatusReply status{TurntableState::kMoving, true, Fault::kNone, 123, 1600, 6400, 3200};
  const std::vector<std::uint8_t> frame = encode_reply(9, status);
  headctl_turntable_status read{};
  ASSERT_EQ(headctl_c_read_turntable_status(frame.data(), frame.size(), &read), 0);
  EXPECT_EQ(read.state, HEADCTL_TURNTABLE_MOVING);
  EXPECT_EQ(read.homed, 1);
  EXPECT_EQ(read.position_step, 123u);
  EXPECT_EQ(read.target_step, 1600u);
  EXPECT_EQ(read.steps_per_revolution, 6400u);
  EXPECT_EQ(read.speed_steps_per_s, 3200u);
  std::vector<std::uint8_t> corrupt = frame;
  corrupt[HEADCTL_FRAME_HEADER_SIZE + 5] ^= 0x10;
  EXPECT_EQ(headctl_c_read_turntable_status(corrupt.data(), corrupt.size(), &read), -1);
}

TEST(HeadctlCodec, EveryRequestTypeRoundTrips) {
  std::set<std::size_t> alternatives;
  std::set<MessageType> types;
  for (const Request& request : request_samples()) {
    alternatives.insert(request.index());
    types.insert(type_of(request));
    for (const int sequence : {0, 1, 127, 255}) {
      const std::vector<std::uint8_t> bytes = encode_request(static_cast<std::uint8_t>(sequence), request);
      const Frame frame = decode_frame(bytes.data(), bytes.size());
      EXPECT_EQ(frame.sequence, sequence);
      EXPECT_FALSE(frame.is_reply());
      EXPECT_EQ(decode_request(frame), request) << message_type_name(type_of(request));
      EXPECT_EQ(encode_frame(frame), bytes);
    }
  }
  EXPECT_EQ(alternatives.size(), std::variant_size_v<Request>) << "a request type has no sample";
  EXPECT_EQ(types.size(), 14u);
}

TEST(HeadctlCodec, EveryReplyTypeRoundTrips) {
  std::set<std::size_t> alternatives;
  for (const Reply& reply : reply_samples()) {
    alternatives.insert(reply.index());
    const std::vector<std::uint8_t> bytes = encode_reply(200, reply);
    const Frame frame = decode_frame(bytes.data(), bytes.size());
    EXPECT_TRUE(frame.is_reply());
    EXPECT_EQ(frame.is_error(), std::holds_alternative<ErrorReply>(reply));
    EXPECT_EQ(frame.type, reply_type(reply));
    EXPECT_EQ(decode_reply(frame), reply) << message_type_name(reply_type(reply));
  }
  EXPECT_EQ(alternatives.size(), std::variant_size_v<Reply>) << "a reply type has no sample";
}

TEST(HeadctlCodec, PayloadSizesAreThoseOfTheCHeader) {
  auto payload_size = [](const std::vector<std::uint8_t>& frame) {
    return frame.size() - HEADCTL_FRAME_HEADER_SIZE - HEADCTL_FRAME_CRC_SIZE;
  };
  EXPECT_EQ(payload_size(encode_reply(0, IdentifyReply{})), HEADCTL_IDENTIFY_REPLY_SIZE);
  EXPECT_EQ(payload_size(encode_request(0, TriggerConfigureRequest{})), HEADCTL_TRIGGER_CONFIGURE_REQUEST_SIZE);
  EXPECT_EQ(payload_size(encode_request(0, TriggerArmRequest{})), HEADCTL_TRIGGER_ARM_REQUEST_SIZE);
  EXPECT_EQ(payload_size(encode_reply(0, TriggerFireReply{})), HEADCTL_TRIGGER_FIRE_REPLY_SIZE);
  EXPECT_EQ(payload_size(encode_reply(0, TriggerStatusReply{})), HEADCTL_TRIGGER_STATUS_REPLY_SIZE);
  EXPECT_EQ(payload_size(encode_request(0, TurntableMoveRequest{})), HEADCTL_TURNTABLE_MOVE_REQUEST_SIZE);
  EXPECT_EQ(payload_size(encode_reply(0, TurntableStatusReply{})), HEADCTL_TURNTABLE_STATUS_REPLY_SIZE);
  EXPECT_EQ(payload_size(encode_reply(0, TurntablePositionReply{})), HEADCTL_TURNTABLE_POSITION_REPLY_SIZE);
  EXPECT_EQ(payload_size(encode_reply(0, TemperaturesReply{{{0, 1}, {1, 2}}})), 1 + 2 * HEADCTL_TEMPERATURE_ENTRY_SIZE);
  EXPECT_EQ(payload_size(encode_reply(0, ErrorLogReply{{ErrorLogEntry{}}})), 1 + HEADCTL_ERROR_LOG_ENTRY_SIZE);
  EXPECT_EQ(payload_size(encode_reply(0, ErrorReply{1, DeviceError::kBusy, 0, "abc"})),
            HEADCTL_ERROR_REPLY_MIN_SIZE + 3);
}

TEST(HeadctlFrame, EverySingleBitErrorAndTruncationIsRejected) {
  std::vector<std::vector<std::uint8_t>> frames;
  for (const Request& request : request_samples()) frames.push_back(encode_request(77, request));
  for (const Reply& reply : reply_samples()) frames.push_back(encode_reply(78, reply));
  for (const auto& frame : frames) {
    for (std::size_t byte = 0; byte < frame.size(); ++byte) {
      for (int bit = 0; bit < 8; ++bit) {
        std::vector<std::uint8_t> corrupt = frame;
        corrupt[byte] = static_cast<std::uint8_t>(corrupt[byte] ^ (1u << bit));
        EXPECT_THROW(decode_frame(corrupt.data(), corrupt.size()), Error) << "byte " << byte << " bit " << bit;
      }
    }
    for (std::size_t size = 0; size < frame.size(); ++size) {
      EXPECT_THROW(decode_frame(frame.data(), size), Error) << "truncated to " << size;
    }
    std::vector<std::uint8_t> longer = frame;
    longer.push_back(0);
    EXPECT_THROW(decode_frame(longer.data(), longer.size()), Error);
  }
}

// Builds a frame around a hand-made payload (valid CRC), to test payload checks.
Frame frame_with(std::uint8_t flags, MessageType type, std::vector<std::uint8_t> payload) {
  Frame frame;
  frame.flags = flags;
  frame.type = static_cast<std::uint8_t>(type);
  frame.payload = std::move(payload);
  return frame;
}

std::string error_of(const Frame& frame, bool reply) {
  try {
    if (reply) (void)decode_reply(frame);
    else (void)decode_request(frame);
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kDevice);
    return error.what();
  }
  return "no error";
}

TEST(HeadctlCodec, MalformedPayloadsAreClearErrors) {
  const std::uint8_t reply = HEADCTL_FLAG_REPLY;
  // Size: one byte short, one too many.
  std::vector<std::uint8_t> move(HEADCTL_TURNTABLE_MOVE_REQUEST_SIZE, 0);
  EXPECT_EQ(error_of(frame_with(0, MessageType::kTurntableMove, move), false), "no error");
  move.push_back(0);
  EXPECT_NE(error_of(frame_with(0, MessageType::kTurntableMove, move), false).find("trailing"), std::string::npos);
  move.resize(HEADCTL_TURNTABLE_MOVE_REQUEST_SIZE - 1);
  EXPECT_NE(error_of(frame_with(0, MessageType::kTurntableMove, move), false).find("truncated"), std::string::npos);
  EXPECT_NE(error_of(frame_with(0, MessageType::kIdentify, {0}), false).find("trailing"), std::string::npos);
  // Reserved byte, enum, bool.
  std::vector<std::uint8_t> configure(HEADCTL_TRIGGER_CONFIGURE_REQUEST_SIZE, 0);
  configure[HEADCTL_TRIGGER_CONFIGURE_OFF_PULSE_WIDTH_US] = 1;
  EXPECT_EQ(error_of(frame_with(0, MessageType::kTriggerConfigure, configure), false), "no error");
  configure[HEADCTL_TRIGGER_CONFIGURE_OFF_RESERVED] = 1;
  EXPECT_NE(error_of(frame_with(0, MessageType::kTriggerConfigure, configure), false).find("reserved"), std::string::npos);
  configure[HEADCTL_TRIGGER_CONFIGURE_OFF_RESERVED] = 0;
  configure[HEADCTL_TRIGGER_CONFIGURE_OFF_POLARITY] = 2;
  EXPECT_NE(error_of(frame_with(0, MessageType::kTriggerConfigure, configure), false).find("polarity"), std::string::npos);
  configure[HEADCTL_TRIGGER_CONFIGURE_OFF_POLARITY] = 0;
  configure[HEADCTL_TRIGGER_CONFIGURE_OFF_ENABLED] = 2;
  EXPECT_NE(error_of(frame_with(0, MessageType::kTriggerConfigure, configure), false).find("not 0 or 1"), std::string::npos);
  // Counts over their maximum; strings that are not printable or have bytes after the NUL.
  EXPECT_NE(error_of(frame_with(reply, MessageType::kTemperatures, {9}), true).find("more than"), std::string::npos);
  std::vector<std::uint8_t> identify = encode_reply(0, IdentifyReply{});
  identify.erase(identify.begin(), identify.begin() + HEADCTL_FRAME_HEADER_SIZE);
  identify.resize(HEADCTL_IDENTIFY_REPLY_SIZE);
  identify[HEADCTL_IDENTIFY_OFF_SERIAL] = 0x07;
  EXPECT_NE(error_of(frame_with(reply, MessageType::kIdentify, identify), true).find("printable"), std::string::npos);
  identify[HEADCTL_IDENTIFY_OFF_SERIAL] = 0;
  identify[HEADCTL_IDENTIFY_OFF_SERIAL + 3] = 'A';
  EXPECT_NE(error_of(frame_with(reply, MessageType::kIdentify, identify), true).find("NUL"), std::string::npos);
  // Error replies: code out of range, text longer than announced or than allowed.
  EXPECT_NE(error_of(frame_with(reply | HEADCTL_FLAG_ERROR, MessageType::kTurntableMove, {0x0A, 0, 0, 0, 0, 0, 0}), true)
                .find("error code"),
            std::string::npos);
  EXPECT_NE(error_of(frame_with(reply | HEADCTL_FLAG_ERROR, MessageType::kTurntableMove, {1, 0, 0, 0, 0, 0, 2, 'a'}), true)
                .find("truncated"),
            std::string::npos);
  EXPECT_NE(error_of(frame_with(reply | HEADCTL_FLAG_ERROR, MessageType::kTurntableMove, {1, 0, 0, 0, 0, 0, 65}), true)
                .find("exceeds"),
            std::string::npos);
  // Direction confusion and unknown types.
  EXPECT_NE(error_of(frame_with(reply, MessageType::kIdentify, {}), false).find("reply"), std::string::npos);
  EXPECT_NE(error_of(frame_with(0, MessageType::kTurntableStatus, {}), true).find("reply bit"), std::string::npos);
  Frame unknown = frame_with(reply, MessageType::kIdentify, {});
  unknown.type = 0x7F;
  EXPECT_NE(error_of(unknown, true).find("type 0x7f"), std::string::npos);
  EXPECT_FALSE(is_known_message_type(0x7F));
  // An acknowledgement for a request whose reply carries data.
  EXPECT_NE(error_of(frame_with(reply, MessageType::kTurntableStatus, {}), true).find("truncated"), std::string::npos);
}

TEST(HeadctlFrame, HeaderDefectsAreNamed) {
  std::vector<std::uint8_t> frame = encode_request(5, TurntableHomeRequest{});
  auto message = [](std::vector<std::uint8_t> bytes) -> std::string {
    try {
      (void)decode_frame(bytes.data(), bytes.size());
    } catch (const Error& error) {
      return error.what();
    }
    return "no error";
  };
  std::vector<std::uint8_t> bad = frame;
  bad[0] = 0x55;
  EXPECT_NE(message(bad).find("sync"), std::string::npos);
  bad = frame;
  bad[HEADCTL_FRAME_OFF_VERSION] = 2;
  try {
    (void)decode_frame(bad.data(), bad.size());
    FAIL();
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kVersionMismatch);
  }
  bad = frame;
  bad[HEADCTL_FRAME_OFF_LENGTH] = 0xF1;  // 241 > the maximum payload
  EXPECT_NE(message(bad).find("exceeds"), std::string::npos);
  bad = frame;
  bad.back() ^= 1;
  EXPECT_NE(message(bad).find("CRC"), std::string::npos);
  std::uint8_t sequence = 0;
  EXPECT_TRUE(peek_sequence(frame.data(), frame.size(), &sequence));
  EXPECT_EQ(sequence, 5);
  EXPECT_FALSE(peek_sequence(frame.data(), 4, &sequence));
}

TEST(HeadctlCodec, EncoderRejectsWhatCannotRoundTrip) {
  IdentifyReply id;
  id.serial = std::string(HEADCTL_SERIAL_SIZE + 1, 'a');
  EXPECT_THROW(encode_reply(0, id), Error);
  id.serial = "tab\there";
  EXPECT_THROW(encode_reply(0, id), Error);
  EXPECT_THROW(encode_reply(0, ErrorReply{1, DeviceError::kBusy, 0, std::string(65, 'x')}), Error);
  EXPECT_THROW(encode_reply(0, ErrorReply{1, static_cast<DeviceError>(0), 0, ""}), Error);
  EXPECT_THROW(encode_reply(0, TemperaturesReply{std::vector<Temperature>(9)}), Error);
  EXPECT_THROW(encode_reply(0, Acknowledge{MessageType::kIdentify}), Error);
  EXPECT_THROW(encode_request(0, TurntableMoveRequest{0, static_cast<Direction>(3), 0}), Error);
  Frame big;
  big.payload.resize(HEADCTL_MAX_PAYLOAD + 1);
  EXPECT_THROW(encode_frame(big), Error);
  Frame flagged;
  flagged.flags = 0x04;
  EXPECT_THROW(encode_frame(flagged), Error);
}

}  // namespace
}  // namespace sls::fwif::headctl
