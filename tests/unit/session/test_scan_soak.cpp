// Long runs (issue 19): a simulated turntable revolution replayed back to back, host (and, with
// a device, GPU) memory sampled after each revolution and the time per frame kept.
//  - ManyScansInOneProcess: a new ScanSession per revolution (an application scanning object
//    after object): nothing may be left behind by a finished scan.
//  - OneLongScan: revolution after revolution into ONE session (a long scan): the moving
//    volume's moves, the tracker and the turntable checks must not leak (time per frame is
//    printed; its trend is bench_soak's); with revisits merged (RevisitPolicy: kMerge, and the
//    default, from the second revolution on), the model and memory stay flat.
// Revolutions: SLS_SOAK_REVOLUTIONS (default 5: CI, ASan included; bench_soak runs 20).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "sdk/core/recording.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_session.h"
#include "tests/support/model_size.h"
#include "tests/support/process_memory.h"
#include "tests/support/test_support.h"
#include "tests/unit/session/sim_frames.h"

namespace sls::session {
namespace {

using test::gpu_used_mib;
using test::heap_mib;
using test::kMiB;
using test::median;
using test::rss_mib;
using test::settled_rss_mib;

// 24 steps of 15°: the views overlap enough to track with the prior (45° do not, issue 19
// item 11), and a revolution costs ~24 small frames.
constexpr int kFramesPerRevolution = 24;

int soak_revolutions() {
  const char* value = std::getenv("SLS_SOAK_REVOLUTIONS");
  const int n = value != nullptr ? std::atoi(value) : 5;
  return std::max(n, 4);  // the first is warm-up, and a trend needs at least three after it
}

using test::model_mib;

struct Revolution {
  double rss_mib = 0.0, heap_mib = 0.0, gpu_mib = 0.0;
  double volume_mib = 0.0;  // the session's volume buffers
  double model_mib = 0.0;   // the long scan's model (model_mib())
  double median_ms = 0.0;   // per frame, the session's stages (read included)
  double fastest_ms = 0.0;  // the revolution's fastest frame: what load on the machine cannot inflate
  std::size_t fused = 0;
};

// One recording for the whole suite (writing it is the slow part).
class ScanSoak : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TemporaryDirectory();
    sim::SimRecordingOptions sim_options;
    sim_options.object = "knurled-knob";
    sim_options.rig.preset = "ci";
    sim_options.rig.frames = kFramesPerRevolution;
    sim_options.rig.camera_width = 240;  // 240 x 180: the CI budget (~60 s on 2 cores)
    sim_options.depth_mode = true;       // the session, not the decoder, is soaked here
    sim::write_sim_recording(dir_->file("rec"), sim_options, Device::cpu(), {});
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static RecordingReader recording() { return RecordingReader::open(dir_->file("rec")); }
  static ScanSessionOptions options(const Device& device) {
    ScanSessionOptions o = small_options(device);
    o.turntable_prior = true;  // depth alone turns the knob wrong (test_scan_session.cpp)
    o.max_voxels = 1e6;        // the CI budget; the volume still moves every frame
    return o;
  }


 public:
  // What the long scan also gives back: from which frame revisits were merged.
  struct LongScan {
    std::vector<Revolution> revolutions;
    std::optional<int> merged_from;
    std::vector<std::size_t> nodes;  // the deformation graph's after each revolution (with deformation)
  };

 protected:
  static LongScan long_scan(RevisitPolicy policy, int revolutions, bool deformation = false,
                            const Device& device = Device::cpu());

  // A new session per revolution; memory sampled after each scan and its model are gone.
  static std::vector<Revolution> many_scans(const Device& device, int revolutions) {
    const RecordingReader rec = recording();
    std::vector<Revolution> out;
    for (int r = 0; r < revolutions; ++r) {
      Revolution rev;
      std::vector<double> ms;
      {
        ScanSession session(rec.calibration(), nullptr, options(device));
        run_recording(session, rec, nullptr, [&](const FrameReport& report) { ms.push_back(report.times.total_ms()); });
        rev.fused = session.fused_count();
        rev.volume_mib = static_cast<double>(session.volume_bytes()) / kMiB;
        const fusion::ExtractedSurface model = session.final_surface();  // what a scan ends with
        EXPECT_GT(model.cloud.size(), 1000u);
      }
      rev.median_ms = median(ms);
      rev.fastest_ms = *std::min_element(ms.begin(), ms.end());
      rev.rss_mib = settled_rss_mib();
      rev.heap_mib = heap_mib();
      rev.gpu_mib = gpu_used_mib();
      out.push_back(rev);
      std::printf(
          "[ measured ] scan %d: %zu of %d fused, %.2f ms/frame (fastest %.2f), RSS %.1f MiB, heap %.2f MiB, GPU %.1f "
          "MiB, volume %.1f MiB\n",
          r, rev.fused, kFramesPerRevolution, rev.median_ms, rev.fastest_ms, rev.rss_mib, rev.heap_mib, rev.gpu_mib,
          rev.volume_mib);
    }
    return out;
  }

  static test::TemporaryDirectory* dir_;
};
test::TemporaryDirectory* ScanSoak::dir_ = nullptr;

// Bounds. Warm-up (first-use caches, thread pools, the allocator's arenas) happens in the first
// revolution, so trends are taken from the second on. The heap between scans holds ~0.2 MiB and
// moved by 0.01 MiB over 5 scans (measured); a leak of one 240 x 180 depth map per scan (0.16
// MiB) exceeds the 0.25 MiB bound within the default run's three compared scans. RSS is taken
// after malloc_trim has returned the allocator's free pages (settled_rss_mib): untrimmed it
// moved by up to 10 MiB between identical scans, up and down (2026-11-29), trimmed by 1.4 MiB.
// Its bound, 8 MiB, is less than one leaked session's volume buffers (volume MiB, printed).
// Time is printed, not asserted: on a shared 2-core machine under ASan even a revolution's
// fastest frame moved by 4x between revolutions (CI, measured), so any bound either fails at
// random or is too loose to catch anything. Whether a frame's cost grows with the run is what
// bench_soak measures (docs/benchmarks.md, "Soak").
constexpr double kHeapGrowthMiB = 0.25;
constexpr double kRssGrowthMiB = 8.0;

void expect_flat(const std::vector<Revolution>& revs, bool check_rss) {
  const Revolution& first = revs[1];
  const Revolution& last = revs.back();
  EXPECT_LT(last.heap_mib - first.heap_mib, kHeapGrowthMiB)
      << "heap grew from " << first.heap_mib << " to " << last.heap_mib << " MiB";
  if (check_rss) {
    EXPECT_LT(last.rss_mib - first.rss_mib, kRssGrowthMiB)
        << "RSS grew from " << first.rss_mib << " to " << last.rss_mib << " MiB";
  }
  for (const Revolution& rev : revs) EXPECT_EQ(rev.fused, revs[0].fused);  // every scan the same
}

#if defined(SLS_SOAK_ASAN)
constexpr bool kCheckRss = false;  // ASan's quarantine holds freed blocks: RSS climbs by design
#else
constexpr bool kCheckRss = true;
#endif

TEST_F(ScanSoak, ManyScansInOneProcessLeaveNothingBehind) {
  const std::vector<Revolution> revs = many_scans(Device::cpu(), soak_revolutions());
  EXPECT_GE(revs[0].fused, static_cast<std::size_t>(kFramesPerRevolution - 2));
  expect_flat(revs, kCheckRss);
}

// Revolution after revolution into one session, the turntable's angle counting on (as a real
// turntable's encoder would) and timestamps continuing. Online deformation off: its graph gains
// a node per keyframe by design (a scan is one revolution, then close_loop()), so over 20
// revolutions it grows without bound and its solves with it; with it off, what must stay flat is
// the session itself: volume moves, tracker, raycaster.
// Revolution after revolution into one session (by default deformation off: its graph gains a
// node per keyframe by design); revisited surface as `policy` says.
ScanSoak::LongScan ScanSoak::long_scan(RevisitPolicy policy, int revolutions, bool deformation, const Device& device) {
  const RecordingReader rec = recording();
  ScanSessionOptions o = options(device);
  o.deformation.enabled = deformation;
  o.revisits = policy;
  ScanSession session(rec.calibration(), nullptr, o);
  const std::int64_t period_ns = rec.frame(rec.frame_count() - 1).timestamp_ns - rec.frame(0).timestamp_ns +
                                 (rec.frame(1).timestamp_ns - rec.frame(0).timestamp_ns);
  std::vector<Revolution> revs;
  std::vector<std::size_t> nodes;
  for (int r = 0; r < revolutions; ++r) {
    std::vector<double> ms;
    const std::size_t fused_before = session.fused_count();
    for (std::size_t i = 0; i < rec.frame_count(); ++i) {
      const FrameInfo& info = rec.frame(i);
      ScanFrame frame;
      frame.index = info.index + r * static_cast<int>(rec.frame_count());
      frame.timestamp_ns = info.timestamp_ns + r * period_ns;
      if (info.turntable_angle_deg) frame.turntable_angle_deg = *info.turntable_angle_deg + 360.0 * r;
      frame.depth_m = rec.load_depth_m(i);
      const FrameReport report = session.add_frame(frame);
      ms.push_back(report.times.total_ms());
    }
    Revolution rev;
    rev.fused = session.fused_count() - fused_before;
    rev.median_ms = median(ms);
    rev.fastest_ms = *std::min_element(ms.begin(), ms.end());
    rev.rss_mib = settled_rss_mib();
    rev.heap_mib = heap_mib();
    rev.model_mib = model_mib(session.final_surface_undeformed());
    revs.push_back(rev);
    if (deformation) nodes.push_back(session.graph_summary().nodes);
    std::printf(
        "[ measured ] long scan (revisits %s), revolution %d: %zu of %d fused, %.2f ms/frame (fastest %.2f), RSS %.1f MiB, heap %.2f "
        "MiB, "
        "model %.2f MiB, %zu moves\n",
        revisit_policy_name(policy), r, rev.fused, kFramesPerRevolution, rev.median_ms, rev.fastest_ms, rev.rss_mib, rev.heap_mib, rev.model_mib,
        session.moves());
  }
  return {revs, session.revisits_merged_from(), nodes};
}

TEST_F(ScanSoak, OneLongScanGrowsOnlyByItsModel) {
  const LongScan scan = long_scan(RevisitPolicy::kKeep, soak_revolutions());
  EXPECT_FALSE(scan.merged_from.has_value());
  const std::vector<Revolution>& revs = scan.revolutions;
  const Revolution& first = revs[1];
  const Revolution& last = revs.back();
  // Memory is not flat here, by design: every move ships the surface leaving the volume, and a
  // revisited surface is shipped again, so the model grows by about a revolution's surface per
  // revolution. What must hold: the heap's growth is the model's. The shipped arrays grow by
  // doubling (capacity up to twice the size), hence 2 x the last model less the first, plus
  // 4 MiB for the per-frame reports (~1 KiB each) and the allocator.
  const double allowed_mib = 2.0 * last.model_mib - first.model_mib + 4.0;
  EXPECT_LT(last.heap_mib - first.heap_mib, allowed_mib)
      << "heap " << first.heap_mib << " -> " << last.heap_mib << " MiB, model " << first.model_mib << " -> "
      << last.model_mib << " MiB";
  EXPECT_GT(last.model_mib, first.model_mib);  // the model does grow: the bound above is not vacuous
  for (const Revolution& rev : revs) EXPECT_EQ(rev.fused, revs[0].fused);
}

// The same long scan with revisits merged from the start: each pass after the first ships only
// what the earlier ones missed, so the model and the heap stay flat (the per-frame reports,
// ~1 KiB a frame, are what still grows: 4 MiB allowed for them and the allocator). Three
// revolutions at most (CI's time): the second pass is where an unmerged model doubles.
TEST_F(ScanSoak, OneLongScanWithMergedRevisitsStaysFlat) {
  const LongScan scan = long_scan(RevisitPolicy::kMerge, std::min(soak_revolutions(), 3));
  EXPECT_EQ(scan.merged_from, 0);
  const std::vector<Revolution>& revs = scan.revolutions;
  const Revolution& first = revs[1];
  const Revolution& last = revs.back();
  const double one_revolution_mib = revs[1].model_mib - revs[0].model_mib;  // what a pass adds unmerged
  EXPECT_LT(last.model_mib - first.model_mib, 0.1 * std::max(first.model_mib, 1.0))
      << "model " << first.model_mib << " -> " << last.model_mib << " MiB (one pass " << one_revolution_mib << ")";
  EXPECT_LT(last.heap_mib - first.heap_mib, 4.0 + 0.2 * first.model_mib)
      << "heap " << first.heap_mib << " -> " << last.heap_mib << " MiB";
  for (const Revolution& rev : revs) EXPECT_EQ(rev.fused, revs[0].fused);
}

// The default (RevisitPolicy::kAfterFirstRevolution), with online deformation as a scan has it:
// the first revolution ships every pass, as kKeep does, then merging begins once the turntable
// has turned a revolution and one move's rotation (15 degrees: one 15-degree step), so the second
// revolution adds next to nothing where kKeep adds a whole copy; and the graph stops growing
// there (DeformationOptions::first_revolution_only): every 15-degree step is a keyframe (over
// node_angle_deg), and of the second revolution's only the frames at 360 and 375 degrees, fed
// before the turn they complete is counted.
void expect_merged_from_the_second_revolution(const ScanSoak::LongScan& scan) {
  const int step_deg = 360 / kFramesPerRevolution;
  const int max_rotation_deg = static_cast<int>(fusion::MovingVolumeOptions().max_rotation_deg);
  EXPECT_EQ(scan.merged_from, (360 + max_rotation_deg + step_deg - 1) / step_deg);
  const std::vector<Revolution>& revs = scan.revolutions;
  EXPECT_LT(revs[1].model_mib - revs[0].model_mib, 0.1 * revs[0].model_mib)
      << "model " << revs[0].model_mib << " -> " << revs[1].model_mib << " MiB";
  for (const Revolution& rev : revs) EXPECT_EQ(rev.fused, revs[0].fused);
  ASSERT_EQ(scan.nodes.size(), revs.size());
  EXPECT_EQ(scan.nodes[0], static_cast<std::size_t>(kFramesPerRevolution));
  EXPECT_EQ(scan.nodes[1], scan.nodes[0] + 2);
}

TEST_F(ScanSoak, OneLongScanByDefaultMergesFromItsSecondRevolution) {
  EXPECT_EQ(ScanSessionOptions().revisits, RevisitPolicy::kAfterFirstRevolution);
  expect_merged_from_the_second_revolution(long_scan(ScanSessionOptions().revisits, 2, /*deformation=*/true));
}

#if defined(SLS_HAVE_CUDA)
// The same on a GPU, where each move's surface ships beside the frame loop: merging begins
// after the pending ship is in.
TEST_F(ScanSoak, OneLongScanOnTheGpuByDefaultMergesFromItsSecondRevolution) {
  SLS_REQUIRE_CUDA_DEVICE();
  expect_merged_from_the_second_revolution(
      long_scan(ScanSessionOptions().revisits, 2, /*deformation=*/true, Device::cuda(0)));
}
// RSS on a GPU host: the frame loop's OpenMP team (a thread per core) and the ships' worker each
// allocate from a malloc arena of their own, whose freed memory glibc keeps; on a 16-core H200
// host RSS climbs by ~20 MiB over the first ~6 scans and then levels off (166-169 MiB over scans
// 9-13), while the bytes in use over all arenas (heap, mallinfo2) stay flat; with
// MALLOC_ARENA_MAX=2, RSS is flat from the first scan (2026-11-29, docs/reliability.md). So ten
// scans here, and RSS compared over the second half: what keeps growing there is a leak.
TEST_F(ScanSoak, ManyScansOnTheGpuLeaveNoDeviceMemoryBehind) {
  SLS_REQUIRE_CUDA_DEVICE();
  const std::vector<Revolution> revs = many_scans(Device::cuda(0), std::max(soak_revolutions(), 10));
  // Device memory is allocated in whole buffers: a leaked volume or depth buffer is whole
  // MiB; the driver's own pools move by less than 2 MiB.
  EXPECT_LT(revs.back().gpu_mib - revs[1].gpu_mib, 2.0) << revs[1].gpu_mib << " -> " << revs.back().gpu_mib << " MiB";
  expect_flat(revs, false);
  const Revolution& middle = revs[revs.size() / 2];
  if (kCheckRss) {
    EXPECT_LT(revs.back().rss_mib - middle.rss_mib, kRssGrowthMiB)
        << "RSS grew from " << middle.rss_mib << " to " << revs.back().rss_mib << " MiB over the second half";
  }
}
#endif

}  // namespace
}  // namespace sls::session
