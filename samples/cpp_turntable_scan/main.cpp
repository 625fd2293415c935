// The same turntable scan as samples/c_turntable_scan, from C++: the C API's handles held by
// std::unique_ptr, its errors thrown as exceptions, the frame callback a lambda.
//
//   cpp_turntable_scan CALIBRATION.yml OUT_FOLDER [FRAMES] [DEVICE_URI]
//
// Build against an installed slscan with the CMakeLists.txt beside this file.
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>

#include <sls/sls.h>

namespace {

// An sls_status other than SLS_OK as an exception carrying the library's message.
class SlsError : public std::runtime_error {
 public:
  SlsError(sls_status status, sls_error* error)
      : std::runtime_error(std::string(sls_error_function(error)) + ": " + sls_status_str(status) + ": " +
                           sls_error_message(error)),
        status_(status) {
    sls_error_free(error);
  }
  sls_status status() const { return status_; }

 private:
  sls_status status_;
};

// Calls an sls_* function whose last argument is the sls_error** out-parameter.
template <typename Function, typename... Args>
void check(Function function, Args... args) {
  sls_error* error = nullptr;
  const sls_status status = function(args..., &error);
  if (status != SLS_OK) throw SlsError(status, error);
}

struct ContextDeleter {
  void operator()(sls_context* context) const { sls_context_destroy(context); }
};
struct ScanDeleter {
  void operator()(sls_scan* scan) const { sls_scan_destroy(scan); }
};
using Context = std::unique_ptr<sls_context, ContextDeleter>;
using Scan = std::unique_ptr<sls_scan, ScanDeleter>;

Scan make_turntable_scan() {
  sls_context* raw_context = nullptr;
  check(sls_context_create, SLS_API_VERSION, static_cast<const sls_context_config*>(nullptr), &raw_context);
  const Context context(raw_context);
  std::printf("%s\n", sls_get_build_info());
  // The defaults (GTSDF, online deformation, an automatic volume), each frame first guessed
  // from the turntable's angle about the calibrated axis.
  sls_scan_config config;
  sls_scan_config_init(&config);
  config.use_turntable_prior = 1;
  sls_scan* raw_scan = nullptr;
  check(sls_scan_create, context.get(), static_cast<const sls_scan_config*>(&config), &raw_scan);
  return Scan(raw_scan);  // the context may go: the scan does not keep it
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3 || argc > 5) {
    std::fprintf(stderr, "usage: %s CALIBRATION.yml OUT_FOLDER [FRAMES] [DEVICE_URI]\n", argv[0]);
    return 2;
  }
  const std::string out = argv[2];
  const std::string recording = out + "/recording";
  const std::string uri = argc > 4 ? argv[4] : "sim://knurled-knob?preset=ci";
  try {
    const Scan scan = make_turntable_scan();
    auto on_frame = [](const sls_frame_report* report, void*) {
      static const char* const kStatus[] = {"fused", "lost", "skipped"};
      std::printf("frame %d of %zu: %s%s%s (%.0f ms)\n", report->index + 1, report->recording_frames,
                  kStatus[report->status], report->reason[0] != '\0' ? ": " : "", report->reason, report->total_ms);
      std::fflush(stdout);
    };
    check(sls_scan_set_frame_callback, scan.get(), static_cast<sls_frame_callback>(on_frame),
          static_cast<void*>(nullptr));

    sls_capture_config capture;
    sls_capture_config_init(&capture);
    capture.camera_uri = uri.c_str();  // the simulated head is camera, projector and turntable
    capture.projector_uri = uri.c_str();
    capture.turntable_uri = uri.c_str();
    capture.calibration_path = argv[1];
    capture.recording_path = recording.c_str();
    capture.frames = argc > 3 ? std::atoi(argv[3]) : 0;  // 0: the turntable's 36 stops
    check(sls_scan_run_devices, scan.get(), static_cast<const sls_capture_config*>(&capture));

    sls_scan_summary summary;
    sls_scan_summary_init(&summary);
    check(sls_scan_get_summary, static_cast<const sls_scan*>(scan.get()), &summary);
    std::printf("fused %zu of %zu frames (%zu lost, %zu skipped), voxels of %.1f um\n", summary.fused,
                summary.frames, summary.lost, summary.skipped, summary.voxel_size_m * 1e6);

    sls_loop_closure loop;
    sls_loop_closure_init(&loop);
    try {
      check(sls_scan_close_loop, scan.get(), &loop);
      std::printf("loop closed: the last pose moved %.1f um, %.4f deg\n", loop.last_pose_correction_m * 1e6,
                  loop.last_pose_correction_deg);
    } catch (const SlsError& error) {  // not a closed loop: the model is written as tracked
      std::printf("loop not closed: %s\n", error.what());
    }

    const std::string cloud = out + "/cloud.ply", mesh = out + "/mesh.ply", trajectory = out + "/trajectory.txt";
    check(sls_scan_write_cloud, static_cast<const sls_scan*>(scan.get()), cloud.c_str());
    check(sls_scan_write_mesh, static_cast<const sls_scan*>(scan.get()), mesh.c_str());
    check(sls_scan_write_trajectory, static_cast<const sls_scan*>(scan.get()), trajectory.c_str());
    std::printf("wrote %s, %s and %s\n", cloud.c_str(), mesh.c_str(), trajectory.c_str());
    return 0;
  } catch (const SlsError& error) {
    std::fprintf(stderr, "the scan failed: %s\n", error.what());
    return 1;
  }
}
