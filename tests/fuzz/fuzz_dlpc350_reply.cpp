// libFuzzer target: what a DLPC350 (or anything posing as one) can send the host. Checks that
// the reply decoder never misbehaves (the sanitizers watch memory and UB), that everything it
// accepts survives an encode/decode round trip, and that the emulated firmware answers any
// bytes a host could send with replies the host can decode.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "firmware-interface/dlpc350/dlpc350_codec.h"
#include "firmware-interface/models/dlpc350_model.h"
#include "sdk/core/error.h"

using namespace sls::fwif;

namespace {

void check(bool condition) {
  if (!condition) std::abort();  // a property violation: libFuzzer saves the input
}

void decode_whole_buffer(const std::uint8_t* data, std::size_t size) {
  dlpc350::Reply reply;
  try {
    reply = dlpc350::decode_reply(data, size);
  } catch (const sls::Error&) {
    return;
  }
  check(reply.data.size() <= dlpc350::kMaxMessageSize);
  std::vector<std::uint8_t> again;
  for (const dlpc350::Report& report : dlpc350::encode_reply(reply)) again.insert(again.end(), report.begin(), report.end());
  check(dlpc350::decode_reply(again.data(), again.size()) == reply);
  // The typed decoders take any reply data without reading past it.
  for (auto decode : {+[](const std::vector<std::uint8_t>& d) { (void)dlpc350::decode_version(d); },
                      +[](const std::vector<std::uint8_t>& d) { (void)dlpc350::decode_exposure(d); },
                      +[](const std::vector<std::uint8_t>& d) { (void)dlpc350::decode_pattern_config(d); },
                      +[](const std::vector<std::uint8_t>& d) { (void)dlpc350::decode_trig_out1(d); },
                      +[](const std::vector<std::uint8_t>& d) { (void)dlpc350::decode_lut_entries(d); }}) {
    try {
      decode(reply.data);
    } catch (const sls::Error&) {
    }
  }
}

// Report by report, as the driver reads them; reports of any length up to 64.
void decode_report_stream(const std::uint8_t* data, std::size_t size) {
  dlpc350::ReplyAssembler assembler;
  std::size_t offset = 0;
  while (offset < size) {
    const std::size_t length = std::min<std::size_t>(data[offset] % 65, size - offset - 1);
    ++offset;
    try {
      (void)assembler.feed(data + offset, length);
    } catch (const sls::Error&) {
      check(!assembler.in_progress());  // an error leaves the assembler ready for a new reply
    }
    offset += length;
  }
}

void feed_the_firmware(const std::uint8_t* data, std::size_t size) {
  models::Dlpc350Model model({}, [] { return std::int64_t{1'000'000}; });
  for (std::size_t offset = 0; offset < size; offset += dlpc350::kReportSize) {
    const std::size_t length = std::min(dlpc350::kReportSize, size - offset);
    check(model.write(dlpc350::kEndpointOut, data + offset, length) == models::TransferOutcome::kDone);
  }
  dlpc350::ReplyAssembler assembler;
  std::vector<std::uint8_t> in;
  while (model.read(dlpc350::kEndpointIn, dlpc350::kReportSize, in) == models::TransferOutcome::kDone) {
    (void)assembler.feed(in.data(), in.size());  // throws (and aborts the fuzzer) if the firmware sent garbage
  }
  check(!assembler.in_progress());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  decode_whole_buffer(data, size);
  decode_report_stream(data, size);
  feed_the_firmware(data, size);
  return 0;
}
