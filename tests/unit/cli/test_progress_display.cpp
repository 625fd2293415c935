// The sls tool's progress display in a log (stderr not a terminal, as under ctest or a pipe): a
// line per tenth of each round of work, with what the round is working on. A head's calibration
// counts its views once per camera: each camera's round must show, not only the first one.
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "samples/sls/progress_display.h"

namespace sls::test {
namespace {

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// The text before the elapsed seconds ("calibrate: 2/4 (50%)") and after them (the detail).
std::string counts_of(const std::string& line) { return line.substr(0, line.find(')') + 1); }
std::string detail_of(const std::string& line) {
  const std::size_t seconds_end = line.find("s", line.find(')') + 2);
  return seconds_end + 1 < line.size() ? line.substr(seconds_end + 2) : "";
}

TEST(ProgressDisplay, EachRoundOfAStageIsShownWithItsDetail) {
  testing::internal::CaptureStderr();
  const ProgressCallback progress = cli::make_progress_display("calibrate");
  for (const char* camera : {"camera0", "camera1"}) {
    for (std::size_t view = 0; view <= 4; ++view) {
      EXPECT_TRUE(progress({"calibrate", view, 4, std::string(camera) + ": view" + std::to_string(view)}));
    }
  }
  EXPECT_TRUE(progress({"report", 1, 1, ""}));
  const std::vector<std::string> lines = lines_of(testing::internal::GetCapturedStderr());
  ASSERT_EQ(lines.size(), 11u) << testing::PrintToString(lines);
  for (std::size_t round = 0; round < 2; ++round) {
    const std::string camera = round == 0 ? "camera0" : "camera1";
    for (std::size_t view = 0; view <= 4; ++view) {
      const std::string& line = lines[round * 5 + view];
      EXPECT_EQ(counts_of(line), "calibrate: " + std::to_string(view) + "/4 (" + std::to_string(view * 25) + "%)");
      EXPECT_EQ(detail_of(line), camera + ": view" + std::to_string(view)) << line;
    }
  }
  EXPECT_EQ(counts_of(lines[10]), "report: 1/1 (100%)");
  EXPECT_EQ(detail_of(lines[10]), "");
}

TEST(ProgressDisplay, ALogGetsALinePerTenthNotPerUpdate) {
  testing::internal::CaptureStderr();
  const ProgressCallback progress = cli::make_progress_display("scan");
  for (std::size_t frame = 0; frame <= 1000; ++frame) EXPECT_TRUE(progress({"scan", frame, 1000, ""}));
  const std::vector<std::string> lines = lines_of(testing::internal::GetCapturedStderr());
  ASSERT_EQ(lines.size(), 11u) << testing::PrintToString(lines);  // 0 %, 10 %, ..., 100 %
  EXPECT_EQ(counts_of(lines.front()), "scan: 0/1000 (0%)");
  EXPECT_EQ(counts_of(lines.back()), "scan: 1000/1000 (100%)");
}

}  // namespace
}  // namespace sls::test
