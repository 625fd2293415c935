// libFuzzer target: pattern-set JSON (a recording's "pattern_set"). Whatever is accepted is a
// valid set that survives a write/read round trip unchanged.
#include <string>

#include "sdk/core/error.h"
#include "sdk/decode/pattern_set.h"
#include "tests/fuzz/fuzz_support.h"

using sls::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  sls::PatternSet set;
  try {
    set = sls::pattern_set_from_json(sls::fuzz::as_text(data, size));
  } catch (const sls::Error&) {
    return 0;
  }
  sls::validate_pattern_set(set);  // an sls::Error here escapes: accepted sets are valid
  const std::string written = sls::pattern_set_to_json(set);
  check(sls::pattern_set_to_json(sls::pattern_set_from_json(written)) == written);
  return 0;
}
