// The DLPC350 USB HID codec: report layout as TI's programmer's guide gives it, multi-report
// messages, typed payloads, and clear errors for malformed or truncated replies.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "firmware-interface/dlpc350/dlpc350_codec.h"
#include "sdk/core/error.h"

namespace sls::fwif::dlpc350 {
namespace {

std::vector<std::uint8_t> concatenate(const std::vector<Report>& reports) {
  std::vector<std::uint8_t> bytes;
  for (const Report& report : reports) bytes.insert(bytes.end(), report.begin(), report.end());
  return bytes;
}

std::string decode_error(const std::vector<std::uint8_t>& bytes) {
  try {
    (void)decode_reply(bytes.data(), bytes.size());
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kDevice);
    return error.what();
  }
  return "no error";
}

TEST(Dlpc350Codec, WriteRequestLayoutIsTisHeaderThenCommandWord) {
  // Pattern display start (0x1A24, data 2), sequence 7, acknowledgement requested.
  const std::vector<Report> reports = encode_request({false, true, 7, 0x1A24, {2}});
  ASSERT_EQ(reports.size(), 1u);
  const Report& r = reports[0];
  EXPECT_EQ(r[0], 0x40);  // write, reply wanted, destination 0
  EXPECT_EQ(r[1], 7);
  EXPECT_EQ(r[2], 3);  // length: 2 command bytes + 1 data byte
  EXPECT_EQ(r[3], 0);
  EXPECT_EQ(r[4], 0x24);  // CMD3
  EXPECT_EQ(r[5], 0x1A);  // CMD2
  EXPECT_EQ(r[6], 2);
  for (std::size_t i = 7; i < kReportSize; ++i) EXPECT_EQ(r[i], 0) << i;
}

TEST(Dlpc350Codec, ReadRequestSetsTheReadAndReplyBits) {
  const Report r = encode_request({true, false, 0x11, static_cast<std::uint16_t>(Command::kGetVersion), {}})[0];
  EXPECT_EQ(r[0], 0xC0);
  EXPECT_EQ(r[1], 0x11);
  EXPECT_EQ(r[2], 2);
  EXPECT_EQ(r[4], 0x05);
  EXPECT_EQ(r[5], 0x02);
}

TEST(Dlpc350Codec, LongMessagesSpanReportsAndReassemble) {
  // The first report carries 58 data bytes after the command word, each continuation 64.
  for (const std::size_t data_size : {0u, 57u, 58u, 59u, 66u, 122u, 123u, 384u, 510u}) {
    Request request{false, true, 3, static_cast<std::uint16_t>(Command::kMailboxData), {}};
    for (std::size_t i = 0; i < data_size; ++i) request.data.push_back(static_cast<std::uint8_t>(i * 7 + 1));
    const std::vector<Report> reports = encode_request(request);
    const std::size_t text = data_size + 2;
    const std::size_t expected_reports = text <= 60 ? 1 : 1 + (text - 60 + 63) / 64;
    EXPECT_EQ(reports.size(), expected_reports) << data_size;
    RequestAssembler assembler;
    for (std::size_t i = 0; i < reports.size(); ++i) {
      const std::optional<Request> done = assembler.feed(reports[i].data(), reports[i].size());
      EXPECT_EQ(done.has_value(), i + 1 == reports.size());
      if (done) {
        EXPECT_EQ(*done, request);
      }
    }
  }
  EXPECT_THROW(encode_request({false, true, 0, 0x1A34, std::vector<std::uint8_t>(511)}), Error);
}

TEST(Dlpc350Codec, RepliesRoundTripThroughReportsAndTheWholeBuffer) {
  for (const std::size_t data_size : {0u, 1u, 16u, 60u, 61u, 124u, 125u, 384u, 512u}) {
    Reply reply{true, false, 200, std::vector<std::uint8_t>(data_size, 0xA5)};
    const std::vector<Report> reports = encode_reply(reply);
    ReplyAssembler assembler;
    std::optional<Reply> done;
    for (const Report& report : reports) done = assembler.feed(report.data(), report.size());
    ASSERT_TRUE(done.has_value());
    EXPECT_EQ(*done, reply);
    const std::vector<std::uint8_t> bytes = concatenate(reports);
    EXPECT_EQ(decode_reply(bytes.data(), bytes.size()), reply);
  }
  const Reply nack{false, true, 9, {}};
  const std::vector<std::uint8_t> bytes = concatenate(encode_reply(nack));
  EXPECT_EQ(bytes[0], 0x60);  // reply + error bits
  EXPECT_TRUE(decode_reply(bytes.data(), bytes.size()).error);
}

TEST(Dlpc350Codec, MalformedAndTruncatedRepliesAreClearErrors) {
  std::vector<std::uint8_t> two = concatenate(encode_reply({true, false, 1, std::vector<std::uint8_t>(100, 1)}));
  std::vector<std::uint8_t> missing(two.begin(), two.begin() + 64);
  EXPECT_NE(decode_error(missing).find("truncated"), std::string::npos);
  std::vector<std::uint8_t> short_continuation(two.begin(), two.begin() + 64 + 10);
  EXPECT_NE(decode_error(short_continuation).find("continuation"), std::string::npos);
  std::vector<std::uint8_t> trailing = two;
  trailing.push_back(0);
  EXPECT_NE(decode_error(trailing).find("follow"), std::string::npos);
  EXPECT_NE(decode_error({0xC0, 1, 2}).find("shorter than the 4-byte header"), std::string::npos);
  EXPECT_NE(decode_error({}).find("header"), std::string::npos);
  EXPECT_NE(decode_error({0x80, 1, 0, 0}).find("reply bit"), std::string::npos);
  EXPECT_NE(decode_error({0xC8, 1, 0, 0}).find("reserved"), std::string::npos);
  EXPECT_NE(decode_error({0xC1, 1, 0, 0}).find("destination"), std::string::npos);
  EXPECT_NE(decode_error({0xC0, 1, 0x01, 0x02}).find("buffer"), std::string::npos);  // length 513
  // A one-report reply that announces more than the report holds.
  EXPECT_NE(decode_error({0xC0, 1, 8, 0, 1, 2, 3}).find("truncated"), std::string::npos);
  // After an error the assembler starts over with the next report.
  ReplyAssembler assembler;
  const std::uint8_t bad[] = {0x00, 1, 0, 0};
  EXPECT_THROW(assembler.feed(bad, sizeof bad), Error);
  const Report good = encode_reply({true, false, 2, {42}})[0];
  const std::optional<Reply> reply = assembler.feed(good.data(), good.size());
  ASSERT_TRUE(reply.has_value());
  EXPECT_EQ(reply->data, std::vector<std::uint8_t>{42});
}

TEST(Dlpc350Codec, LutEntryBitsFollowTheProgrammersGuide) {
  LutEntry entry;
  entry.trigger = LutTrigger::kExternalPositive;  // bits 1:0 = 1
  entry.pattern_number = 2;                       // bits 7:2
  entry.bit_depth = 8;                            // bits 11:8
  entry.leds = kLedWhite;                         // bits 14:12
  entry.invert = true;                            // bit 16
  entry.buffer_swap = true;                       // bit 18
  const auto bytes = encode_lut_entry(entry);
  // 0x1 | 2 << 2 | 8 << 8 | 7 << 12 | 1 << 16 | 1 << 18 = 0x057809
  EXPECT_EQ(bytes[0], 0x09);
  EXPECT_EQ(bytes[1], 0x78);
  EXPECT_EQ(bytes[2], 0x05);
  EXPECT_EQ(decode_lut_entry(bytes.data()), entry);

  for (int trigger = 0; trigger < 4; ++trigger) {
    for (const int pattern : {0, 1, 24, 63}) {
      for (const int depth : {1, 7, 8}) {
        LutEntry e{static_cast<LutTrigger>(trigger), static_cast<std::uint8_t>(pattern), static_cast<std::uint8_t>(depth),
                   static_cast<std::uint8_t>(pattern % 8), pattern % 2 == 0, pattern % 3 == 0, depth == 8, trigger == 3};
        EXPECT_EQ(decode_lut_entry(encode_lut_entry(e).data()), e);
      }
    }
  }
  const std::uint8_t reserved[] = {0x00, 0x88, 0x00};  // bit 15
  EXPECT_THROW(decode_lut_entry(reserved), Error);
  const std::uint8_t high[] = {0x00, 0x08, 0x10};  // bit 20
  EXPECT_THROW(decode_lut_entry(high), Error);
  EXPECT_THROW(encode_lut_entry(LutEntry{LutTrigger::kInternal, 64, 8, 7}), Error);
  EXPECT_THROW(encode_lut_entry(LutEntry{LutTrigger::kInternal, 0, 9, 7}), Error);
  EXPECT_THROW(encode_lut_entry(LutEntry{LutTrigger::kInternal, 0, 0, 7}), Error);
  EXPECT_THROW(decode_lut_entries(std::vector<std::uint8_t>(4)), Error);
}

TEST(Dlpc350Codec, TypedPayloads) {
  const PatternConfig config{22, false, 22, 8};
  EXPECT_EQ(encode_pattern_config(config), (std::vector<std::uint8_t>{21, 0, 21, 7}));  // counts minus one
  EXPECT_EQ(decode_pattern_config(encode_pattern_config(config)), config);
  EXPECT_THROW(encode_pattern_config({129, false, 1, 1}), Error);
  EXPECT_THROW(encode_pattern_config({1, false, 1, 65}), Error);
  EXPECT_THROW(decode_pattern_config({0, 2, 0, 0}), Error);  // repeat must be 0 or 1
  EXPECT_THROW(decode_pattern_config({0, 0, 0}), Error);     // truncated

  const ExposureTiming timing{8333, 10000};
  EXPECT_EQ(encode_exposure(timing), (std::vector<std::uint8_t>{0x8D, 0x20, 0, 0, 0x10, 0x27, 0, 0}));
  EXPECT_EQ(decode_exposure(encode_exposure(timing)), timing);
  EXPECT_THROW(decode_exposure({1, 2, 3, 4, 5, 6, 7}), Error);

  const TriggerOutputConfig trigger{true, 0xC0, 0xB0};
  EXPECT_EQ(encode_trig_out1(trigger), (std::vector<std::uint8_t>{1, 0xC0, 0xB0}));
  EXPECT_EQ(decode_trig_out1(encode_trig_out1(trigger)), trigger);
  EXPECT_EQ(encode_trig_out2(trigger), (std::vector<std::uint8_t>{1, 0xC0}));
  EXPECT_EQ(trigger_delay_code(0.0), kTriggerDelayZero);
  EXPECT_EQ(trigger_delay_code(-20.05), 0x00);
  EXPECT_EQ(trigger_delay_code(1000.0), 0xD5);  // clamped to TI's largest delay
  EXPECT_NEAR(trigger_delay_us(0xD4), 2.68, 0.01);

  const Version version{0x03000001u, 0x02010000u, 0, 0x0102FFFFu};
  EXPECT_EQ(decode_version(encode_version(version)), version);
  EXPECT_EQ(Version::format(version.application), "3.0.1");
  EXPECT_EQ(Version::format(version.sequence_config), "1.2.65535");
  EXPECT_THROW(decode_version(std::vector<std::uint8_t>(15)), Error);

  // TI's reference host code sends a two-entry image LUT swapped; decoding undoes it.
  EXPECT_EQ(encode_image_lut({4, 9}), (std::vector<std::uint8_t>{9, 4}));
  EXPECT_EQ(encode_image_lut({1, 2, 3}), (std::vector<std::uint8_t>{1, 2, 3}));
  EXPECT_EQ(decode_image_lut(encode_image_lut({4, 9})), (std::vector<std::uint8_t>{4, 9}));

  EXPECT_EQ(ValidationStatus{0}.describe(), "valid");
  EXPECT_TRUE(ValidationStatus{0x04}.valid());  // warnings only
  EXPECT_FALSE(ValidationStatus{0x02}.valid());
  EXPECT_NE(ValidationStatus{0x81}.describe().find("exposure"), std::string::npos);
  EXPECT_TRUE(ValidationStatus{0x81}.busy());
  EXPECT_EQ(command_name(Command::kPatternStartStop), "PAT_START_STOP (0x1A24)");
  EXPECT_EQ(command_name(0xBEEF), "0xBEEF");
  EXPECT_THROW(decode_byte({}, Command::kMainStatus), Error);
}

}  // namespace
}  // namespace sls::fwif::dlpc350
