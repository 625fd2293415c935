// libFuzzer target: what a head-controller board (or anything posing as one) can send the
// host, and what a host can send the board. Checks that the frame and payload decoders never
// misbehave (the sanitizers watch memory and UB), that they accept only canonical bytes
// (whatever decodes re-encodes to exactly the input), and that the emulated firmware answers
// every frame with a reply the host can decode.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "firmware-interface/headctl/headctl_codec.h"
#include "firmware-interface/models/headctl_model.h"
#include "sdk/core/error.h"

using namespace sls::fwif;

namespace {

void check(bool condition) {
  if (!condition) std::abort();  // a property violation: libFuzzer saves the input
}

void decode_and_round_trip(const std::vector<std::uint8_t>& bytes) {
  headctl::Frame frame;
  try {
    frame = headctl::decode_frame(bytes.data(), bytes.size());
  } catch (const sls::Error&) {
    return;
  }
  check(headctl::encode_frame(frame) == bytes);
  try {
    if (frame.is_reply()) {
      const headctl::Reply reply = headctl::decode_reply(frame);
      check(headctl::encode_reply(frame.sequence, reply) == bytes);
    } else {
      const headctl::Request request = headctl::decode_request(frame);
      check(headctl::encode_request(frame.sequence, request) == bytes);
    }
  } catch (const sls::Error&) {
  }
}

// The input as header fields and payload, framed with the right sync, version, length and
// CRC, so the fuzzer reaches the payload decoders instead of stopping at the CRC.
std::vector<std::uint8_t> framed(const std::uint8_t* data, std::size_t size) {
  if (size < 3) return {};
  headctl::Frame frame;
  frame.flags = data[0] & 0x03;
  frame.type = data[1];
  frame.sequence = data[2];
  frame.payload.assign(data + 3, data + std::min<std::size_t>(size, 3 + HEADCTL_MAX_PAYLOAD));
  return headctl::encode_frame(frame);
}

void feed_the_firmware(const std::vector<std::uint8_t>& bytes) {
  models::HeadctlModel model({}, [] { return std::int64_t{1'000'000}; });
  check(model.write(HEADCTL_USB_ENDPOINT_OUT, bytes.data(), bytes.size()) == models::TransferOutcome::kDone);
  std::vector<std::uint8_t> in;
  check(model.read(HEADCTL_USB_ENDPOINT_IN, 512, in) == models::TransferOutcome::kDone);  // always an answer
  const headctl::Frame reply = headctl::decode_frame(in.data(), in.size());  // throws (aborts) on garbage
  check(reply.is_reply());
  (void)headctl::decode_reply(reply);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::vector<std::uint8_t> raw(data, data + size);
  decode_and_round_trip(raw);
  feed_the_firmware(raw);
  const std::vector<std::uint8_t> valid = framed(data, size);
  if (!valid.empty()) {
    decode_and_round_trip(valid);
    feed_the_firmware(valid);
  }
  return 0;
}
