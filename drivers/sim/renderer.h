// Renders what the simulated scanner's camera captures, and the ground truth, on the CPU or
// a CUDA GPU (one body of per-pixel code: drivers/sim/render_shared.h).
//
//   Renderer renderer(rig, scene, Device::cuda());
//   renderer.set_frame(k);                    // traces the frame's geometry once
//   Image16u image = renderer.render_pattern(j);   // pattern j of the rig's pattern set
//   GroundTruthFrame truth = renderer.ground_truth();
//
// Noise is keyed by (rig.noise_seed, frame, pattern, pixel): the same on both backends and
// reproducible whatever order frames and patterns are rendered in.
#pragma once

#include <memory>

#include "drivers/sim/rig.h"
#include "drivers/sim/scene.h"
#include "sdk/core/device.h"
#include "sdk/core/image.h"
#include "sdk/core/memory_type.h"
#include "sdk/core/pose.h"
#include "sdk/core/ray_map.h"

namespace sls::sim {

struct GroundTruthFrame {
  int frame = 0;
  double commanded_angle_deg = 0.0;
  double true_angle_deg = 0.0;
  Pose T_world_object;
  Pose T_object_camera;
  Image32f depth_m;       // camera-frame z of the visible surface; 0 where the ray misses
  Image32f projector_u;   // projector pixel coordinates of that point; NaN where not lit
  Image32f projector_v;
  Image8u valid;          // 1 where visible and lit (what a decoder can measure), else 0
  Image32f depth_sigma_m; // the depth-only mode's noise σ per pixel; 0 where not valid
};

class RenderBackend;

class Renderer {
 public:
  // Throws sls::Error: unsupported / device errors for a CUDA device that is not there,
  // out of memory when the images do not fit on the GPU.
  Renderer(SimRig rig, Scene scene, const Device& device);
  ~Renderer();
  Renderer(Renderer&&) noexcept;
  Renderer& operator=(Renderer&&) noexcept;

  const SimRig& rig() const { return rig_; }
  const Scene& scene() const { return scene_; }
  const Device& device() const { return device_; }

  // Traces frame `frame` (0 .. steps_per_revolution − 1, or beyond for a second turn; with
  // rig().placements, 0 .. placements.size() − 1).
  void set_frame(int frame);
  int frame() const { return frame_; }
  // Appends a placement to rig().placements (a calibration capture whose simulated operator
  // places the board as it goes: sim_scanner.h) and returns its frame.
  int add_placement(const ObjectPlacement& placement);

  // Pattern `pattern` of rig().patterns, as the camera's digital numbers.
  Image16u render_pattern(int pattern);
  // The same at `exposure_scale` times the rig's exposure time (HDR capture: all light scales,
  // read noise and the full well do not, so highlights clip at the sensor's full scale), with
  // the noise of exposure `exposure_index` (0 draws as render_pattern(j); 1.. draw anew).
  // sls::Error(kInvalidArgument) for a scale that is not finite and positive, an index
  // outside 0..255.
  Image16u render_pattern(int pattern, double exposure_scale, int exposure_index);
  // Any pattern (e.g. a dark projector: PatternKind::kBlack); `image_key` selects the noise
  // draw within the frame (render_pattern(j) uses j).
  Image16u render(const PatternDesc& pattern, std::uint32_t image_key, double exposure_scale = 1.0);
  // Where render() and render_pattern() put their images (default kHost; kPinned: a simulated
  // camera delivering for a GPU scan).
  void set_image_memory(MemoryType memory) { image_memory_ = memory; }
  // The same, left in device memory (benchmarks: what a GPU pipeline would decode in place).
  void render_pattern_resident(int pattern);
  // Waits for the device (benchmarks).
  void synchronize();

  GroundTruthFrame ground_truth() const;
  // Depth-only mode: the true depth plus the noise a phase-shift decode would have there
  // (render_shared.h); 0 where not valid.
  Image32f render_depth();

 private:
  void require_frame() const;

  SimRig rig_;
  Scene scene_;
  Device device_;
  int frame_ = -1;
  MemoryType image_memory_ = MemoryType::kHost;
  std::unique_ptr<RayMap> rays_;  // the backends read it for every frame
  std::unique_ptr<RenderBackend> backend_;
};

}  // namespace sls::sim
