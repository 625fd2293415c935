// libFuzzer target: device URIs ("sim://name?key=value", "gige://address", plain paths).
// Whatever is accepted has a scheme, answers every typed query with a value or an sls::Error,
// and its text form parses back to the same URI.
#include <string>

#include "drivers/interfaces/device_uri.h"
#include "sdk/core/error.h"
#include "tests/fuzz/fuzz_support.h"

using sls::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  sls::drivers::DeviceUri uri;
  try {
    uri = sls::drivers::parse_device_uri(sls::fuzz::as_text(data, size));
  } catch (const sls::Error&) {
    return 0;
  }
  check(!uri.scheme.empty());
  for (const auto& [key, value] : uri.query) {
    check(uri.get(key, "") == value);
    try {
      (void)uri.get_int(key, 0);
    } catch (const sls::Error&) {
    }
    try {
      (void)uri.get_double(key, 0.0);
    } catch (const sls::Error&) {
    }
  }
  // The text form is parsed again where URIs are keys (shared simulated scanners).
  const sls::drivers::DeviceUri again = sls::drivers::parse_device_uri(uri.to_string());
  check(again.scheme == uri.scheme && again.target == uri.target && again.query == uri.query);
  return 0;
}
