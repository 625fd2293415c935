#include <gtest/gtest.h>

#include "drivers/interfaces/device_uri.h"
#include "sdk/core/error.h"

namespace sls::drivers {
namespace {

TEST(DeviceUri, ParsesSchemeTargetAndQuery) {
  const DeviceUri uri = parse_device_uri("sim://knurled-screw?preset=demo&frames=120&noise=0.5");
  EXPECT_EQ(uri.scheme, "sim");
  EXPECT_EQ(uri.target, "knurled-screw");
  EXPECT_EQ(uri.get("preset", ""), "demo");
  EXPECT_EQ(uri.get_int("frames", 0), 120);
  EXPECT_DOUBLE_EQ(uri.get_double("noise", 0.0), 0.5);
  EXPECT_EQ(uri.get("missing", "fallback"), "fallback");
  EXPECT_EQ(uri.get_int("missing", 7), 7);
  EXPECT_EQ(parse_device_uri(uri.to_string()).query, uri.query);
}

TEST(DeviceUri, PlainPathIsAFile) {
  const DeviceUri uri = parse_device_uri("/data/scan 1");
  EXPECT_EQ(uri.scheme, "file");
  EXPECT_EQ(uri.target, "/data/scan 1");
  EXPECT_EQ(uri.to_string(), "/data/scan 1");
}

TEST(DeviceUri, PercentDecoding) {
  const DeviceUri uri = parse_device_uri("file:///data/scan%201?note=a%2Bb+c");
  EXPECT_EQ(uri.target, "/data/scan 1");
  EXPECT_EQ(uri.get("note", ""), "a+b c");
}

TEST(DeviceUri, MalformedIsAClearError) {
  for (const char* bad : {"", "://x", "s!m://x", "sim://x?a=1&a=2", "sim://x?=3", "sim://x%2", "sim://x%zz"}) {
    EXPECT_THROW(parse_device_uri(bad), Error) << bad;
  }
  const DeviceUri uri = parse_device_uri("sim://x?frames=ten&scale=1.5x");
  try {
    (void)uri.get_int("frames", 0);
    FAIL();
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("frames=ten"), std::string::npos) << error.what();
  }
  EXPECT_THROW((void)uri.get_double("scale", 0.0), Error);
}

// Found by fuzz_device_uri: to_string did not escape what it had decoded, so its text parsed
// back to another URI ("file://tfile://x" gave "tfile://x", of scheme "tfile").
TEST(DeviceUri, TextFormParsesBackToTheSameUri) {
  for (const char* text : {"file://tfile://x", "sim://a%3Fb?name=x%26y%3Dz&k%3D=%2B%25", "file://?a=1", "file://",
                           "sim://x+y?q=a+b", "/plain/path with space", "gige://10.0.0.1"}) {
    const DeviceUri uri = parse_device_uri(text);
    const DeviceUri again = parse_device_uri(uri.to_string());
    EXPECT_EQ(again.scheme, uri.scheme) << text << " -> " << uri.to_string();
    EXPECT_EQ(again.target, uri.target) << text << " -> " << uri.to_string();
    EXPECT_EQ(again.query, uri.query) << text << " -> " << uri.to_string();
  }
  EXPECT_EQ(parse_device_uri("sim://x?name=a%26b").to_string(), "sim://x?name=a%26b");
  EXPECT_EQ(parse_device_uri("/data/scan 1").to_string(), "/data/scan 1");
}

}  // namespace
}  // namespace sls::drivers
