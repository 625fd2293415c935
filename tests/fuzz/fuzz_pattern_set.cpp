// libFuzzer target: pattern-set JSON (a recording's "pattern_set") and pattern descriptions
// (the family form, sdk/decode/pattern_families.h). Whatever is accepted is a valid set that
// survives a write/read round trip unchanged.
#include <string>

#include "sdk/core/error.h"
#include "sdk/decode/pattern_families.h"
#include "sdk/decode/pattern_set.h"
#include "tests/fuzz/fuzz_support.h"

using sls::fuzz::check;

namespace {

template <typename Parse>
void round_trip(const std::string& text, const Parse& parse) {
  sls::PatternSet set;
  try {
    set = parse(text);
  } catch (const sls::Error&) {
    return;
  }
  sls::validate_pattern_set(set);  // an sls::Error here escapes: accepted sets are valid
  const std::string written = sls::pattern_set_to_json(set);
  check(sls::pattern_set_from_json(written) == set);
  check(sls::pattern_set_to_json(sls::pattern_set_from_json(written)) == written);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = sls::fuzz::as_text(data, size);
  round_trip(text, [](const std::string& t) { return sls::pattern_set_from_json(t); });
  round_trip(text, [](const std::string& t) { return sls::pattern_set_from_description(t); });
  return 0;
}
