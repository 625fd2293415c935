// `sls scan` run in-process (samples/sls: the same code as the tool) with a fault of the machine
// injected part-way through the frames (issue 19): the GPU or the host out of memory after some
// frames were fused. Through Context::after_frame, the hook the tool leaves unset: it throws
// as ScanSession::add_frame does when the machine fails (sls::Error, or std::bad_alloc from an
// allocation). What was fused must be written as a valid partial model (every output parses,
// report.json says it was stopped and by what), and the scan must fail naming the fault and the
// files written, exit status 1.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <new>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "drivers/sim/sim_recording.h"
#include "samples/sls/cli.h"
#include "samples/sls/commands.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/ply.h"
#include "sdk/core/trajectory.h"
#include "tests/support/test_support.h"

namespace sls::test {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 4;

class ScanCommandFault : public ::testing::Test {
 protected:
  // A 4-frame turntable recording of the ci preset at 160 x 120 pixels, made once.
  static void SetUpTestSuite() {
    dir_ = new TemporaryDirectory();
    sim::SimRecordingOptions options;
    options.rig.preset = "ci";
    options.rig.frames = kFrames;
    options.rig.camera_width = 160;
    options.reference_spacing_m = 1e-3;
    sim::write_sim_recording(recording(), options, Device::cpu(), {});
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string recording() { return dir_->file("recording"); }

  // Runs `sls scan ARGS` as the tool does, with `after_frame` as the context's hook; returns the
  // exit status and sets `stderr_text` to what it printed there.
  static int run_scan(const std::vector<std::string>& args, std::function<void(int)> after_frame,
                      std::string* stderr_text) {
    cli::Context context;
    context.options.quiet = true;
    context.after_frame = std::move(after_frame);
    CLI::App app{"sls"};
    int exit_code = cli::kExitOk;
    cli::add_scan_command(app, context, &exit_code);
    std::vector<std::string> argv{"scan"};
    argv.insert(argv.end(), args.begin(), args.end());
    std::reverse(argv.begin(), argv.end());  // CLI11 takes them last first
    ::testing::internal::CaptureStderr();
    try {
      app.parse(argv);
    } catch (const CLI::ParseError& error) {
      exit_code = cli::kExitUsage;
      ADD_FAILURE() << "bad command line: " << error.what();
    }
    *stderr_text = ::testing::internal::GetCapturedStderr();
    return exit_code;
  }

  // The partial model in `out`: every output there parses and holds the `fused` frames.
  static void expect_partial_model(const std::string& out, std::size_t fused, const std::string& fault) {
    const PointCloud cloud = read_ply_cloud(out + "/cloud.ply");
    const TriangleMesh mesh = read_ply_mesh(out + "/mesh.ply");
    EXPECT_GT(cloud.size(), 1000u);
    EXPECT_GT(mesh.faces.size(), 1000u);
    EXPECT_EQ(read_tum_trajectory(out + "/trajectory.txt").size(), fused);
    const nlohmann::json report = nlohmann::json::parse(read_file_text(out + "/report.json"));
    EXPECT_EQ(report["frames"], kFrames);
    EXPECT_EQ(report["frames_fused"], fused);
    EXPECT_EQ(report["points"], cloud.size());
    EXPECT_EQ(report["triangles"], mesh.faces.size());
    EXPECT_TRUE(report["interrupted"].get<bool>());
    EXPECT_NE(report["interruption"].get<std::string>().find("stopped by an error: " + fault), std::string::npos)
        << report["interruption"];
    EXPECT_TRUE(fs::is_regular_file(out + "/report.html"));
    for (const fs::directory_entry& entry : fs::directory_iterator(out)) {
      EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
    }
  }

  static TemporaryDirectory* dir_;
  TemporaryDirectory out_dir_;
};

TemporaryDirectory* ScanCommandFault::dir_ = nullptr;

// The GPU (as ScanSession throws it: sls::Error kOutOfMemory) fails after frame 1 was fused.
TEST_F(ScanCommandFault, AFaultAfterFramesWereFusedWritesThemAsAPartialModelAndFailsNamingIt) {
  const std::string out = out_dir_.file("scan");
  const std::string fault = "CUDA out of memory allocating the raycast maps (injected)";
  std::vector<int> seen;
  std::string err;
  const int status = run_scan({"--input", recording(), "--poses", "groundtruth", "--device", "cpu", "--out", out},
                              [&](int frame) {
                                seen.push_back(frame);
                                if (frame == 1) throw Error(ErrorCode::kOutOfMemory, fault);
                              },
                              &err);
  EXPECT_EQ(status, cli::kExitError) << err;
  EXPECT_EQ(seen, (std::vector<int>{0, 1})) << "the frame loop stopped at the fault";
  EXPECT_NE(err.find("sls scan: error: " + fault), std::string::npos) << err;
  EXPECT_NE(err.find("the 2 frame(s) fused before it are written as a valid partial model: " + out +
                     "/render.png, cloud.ply, mesh.ply, trajectory.txt, report.json, report.html"),
            std::string::npos)
      << err;
  expect_partial_model(out, 2, fault);
}

// The host out of memory (std::bad_alloc from an allocation) after frame 2, tracked with the
// turntable prior and online deformation: the model as tracked (undeformed/) is written too.
TEST_F(ScanCommandFault, AHostAllocationThatFailsPartWayIsAFaultOfTheMachineNotAnInternalError) {
  const std::string out = out_dir_.file("scan");
  std::string err;
  const int status = run_scan({"--input", recording(), "--turntable-prior", "--device", "cpu", "--out", out},
                              [&](int frame) {
                                if (frame == 2) throw std::bad_alloc();
                              },
                              &err);
  EXPECT_EQ(status, cli::kExitError) << err;
  EXPECT_EQ(err.find("internal error"), std::string::npos) << err;
  EXPECT_NE(err.find("sls scan: error: out of host memory after 3 of 4 frame(s); the 3 frame(s) fused before it are "
                     "written as a valid partial model: " + out + "/undeformed/cloud.ply, undeformed/trajectory.txt, "
                     "render.png, cloud.ply, mesh.ply, trajectory.txt, report.json, report.html"),
            std::string::npos)
      << err;
  expect_partial_model(out, 3, "out of host memory after 3 of 4 frame(s)");
  EXPECT_FALSE(read_ply_cloud(out + "/undeformed/cloud.ply").empty());
  EXPECT_EQ(read_tum_trajectory(out + "/undeformed/trajectory.txt").size(), 3u);
}

}  // namespace
}  // namespace sls::test
