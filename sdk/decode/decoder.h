// The decode stage (DESIGN.md section 1): a captured pattern stack -> projector coordinates
// -> depth map, on the CPU or a CUDA GPU over one body of per-pixel code
// (decode_shared.h, triangulate_shared.h).
//
//   Decoder decoder(set, calibration, Device::cuda());
//   DecodedFrame frame = decoder.decode(images);           // images in pattern-set order
//   PointCloud cloud = depth_to_cloud(frame, decoder.rays());
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "sdk/core/calibration.h"
#include "sdk/core/device.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/image.h"
#include "sdk/core/point_cloud.h"
#include "sdk/core/ray_map.h"
#include "sdk/decode/decode_shared.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/decode/triangulate_shared.h"

namespace sls {

// Thresholds and the camera's noise model. Defaults: the 12-bit IMX304-class camera of the
// default rig (docs/simulator-optics.md); set the noise model from the camera's EMVA 1288
// figures (or a photon transfer measurement) for another camera.
struct DecodeOptions {
  // Camera levels and temporal noise: variance(I) = (I - black)/gain + read^2 + 1/12 (DN^2).
  int bit_depth = 12;
  double saturation_dn = 0.0;      // samples >= this are saturated; 0: 98 % of 2^bit_depth - 1
                                   // (a pixel clips at its full well a little below the ADC's top)
  double black_level_dn = 32.0;
  double gain_e_per_dn = 2.6;
  double read_noise_dn = 0.92;
  // Shadow: white - black below max(shadow_min_contrast_dn, shadow_contrast_sigma * its noise).
  // 0: 0.4 % of full scale (16 DN at 12 bits, 1 DN at 8 bits), a floor under the noise test
  // for cameras whose noise model is unknown.
  double shadow_min_contrast_dn = 0.0;
  double shadow_contrast_sigma = 6.0;
  // A Gray bit is ambiguous when |pattern - inverse| <= gray_margin_sigma * its noise (only
  // acceptable for one bit: the one whose stripe edge the pixel sits on). Micro phase shifting
  // holds its period search to the same margin (multi_frequency_shared.h).
  double gray_margin_sigma = 3.0;
  // Low modulation: fringe amplitude below min_modulation_ratio * (white - black) / 2, or a
  // predicted coordinate noise above max_phase_sigma_px (projector pixels).
  double min_modulation_ratio = 0.25;
  double max_phase_sigma_px = 0.2;  // 5 sigma = 1 px: keeps noise outliers under a pixel
  // Gray/phase consistency: the unwrapped coordinate may lie this far outside its stripe.
  double consistency_tolerance_px = 2.0;
  // Confidence = 1 / (1 + (sigma / confidence_sigma_px)^2), sigma the predicted noise.
  double confidence_sigma_px = 0.05;
  // Triangulation.
  double min_triangulation_angle_deg = 5.0;
  double min_depth_m = 1e-3;       // camera-frame z range kept (set the scanner's working volume)
  double max_depth_m = 10.0;
  int newton_iterations = 3;
  // Columns and rows coded: largest distance (projector px) of the decoded (u, v) from the
  // pixel's epipolar curve; farther is inconsistent (a misdecode, or a miscalibration).
  double max_epipolar_error_px = 1.5;
  // Refuse a stack whose images do not behave as the pattern set says (stack_check.h): a
  // complementary Gray pair that does not add up to white + black, a phase step off the
  // others' sinusoid.
  bool check_stack = true;

  // Throws sls::Error(kInvalidArgument) naming the first bad value.
  void validate() const;
};

struct DecodedFrame {
  Image32f projector_u;  // projector column coordinate (pixel centres at integers); NaN where not decoded
  Image32f projector_v;  // projector row coordinate; NaN where not decoded or rows not coded
  Image32f confidence;   // [0, 1]; 0 where not decoded
  Image8u mask;          // DecodeMaskBits (decode_shared.h): kDecodeOk where u (and v) and depth are valid
  Image32f depth_m;      // camera-frame z; 0 = invalid

  std::size_t ok_count() const;  // pixels with mask == kDecodeOk
};

// Which images of a DecodedFrame a decode fills.
enum class DecodeOutputs {
  kAll,
  // depth_m and confidence only (projector_u, projector_v and mask left empty): what a scan
  // fuses and tracks from. On a GPU the others stay on the device, not downloaded (108 of
  // the 204 MB a 12-megapixel frame's outputs take).
  kDepthAndConfidence,
  // A CUDA decoder's depth and confidence left on the GPU (depth_on_device(), confidence_on_device()),
  // nothing downloaded and the frame's images left as they were: what a GPU scan fuses and
  // tracks from, downloading the depth map (download_depth) only on the frames that need it on
  // the host. A CPU decoder: as kDepthAndConfidence.
  kDepthAndConfidenceOnDevice,
};

// Where each pattern of `set` is used. Throws sls::Error(kInvalidArgument) for a set the
// decoder cannot use: a Gray bit without the coarser ones above it, bits that do not number
// the whole axis, stripes too wide to unwrap the phase (W >= P), phase steps of mixed N or
// P, more than kDecodeMaxGrayBits / kDecodeMaxPhaseSteps, no columns and no rows, heterodyne
// periods whose beat does not span the axis, micro phase-shifting periods that cannot tell
// the candidates apart (multi_frequency_layout.h).
DecodeLayout make_decode_layout(const PatternSet& set);
DecodeThresholds make_decode_thresholds(const DecodeOptions& options);
TriangulationParams make_triangulation_params(const ScannerCalibration& calibration, const DecodeOptions& options);

class Decoder {
 public:
  // Validates the set, the calibration and the options (sls::Error(kInvalidArgument)),
  // computes the camera's ray map on `device`, and on a CUDA device allocates its buffers.
  // Asking for CUDA in a build without it: sls::Error(kUnsupported). On a GPU, decoding is
  // queued on `stream` and uploads on `upload_stream` (a session's; its own when none is given),
  // and the camera's ray map is shared with the other stages that view through the camera.
  Decoder(const PatternSet& set, const ScannerCalibration& calibration, const Device& device = Device::cpu(),
          const DecodeOptions& options = {}, const GpuStream& stream = {}, const GpuStream& upload_stream = {});
  ~Decoder();
  Decoder(Decoder&&) noexcept;
  Decoder& operator=(Decoder&&) noexcept;

  // Decodes one frame: `stack` holds one image per pattern, in the set's order, each of the
  // calibrated camera's size. Throws sls::Error(kInvalidArgument) naming the problem: wrong
  // image count, an empty or mis-sized image, a size that differs from the calibration's
  // camera, an all-dark stack (no pixel with white - black contrast: projector off?);
  // sls::Error(kFormat) for a stack whose images do not behave as the set says (stack_check.h).
  DecodedFrame decode(const std::vector<Image16u>& stack);
  // The same, into `frame`, filling the images `outputs` names and reusing them when they
  // already have the camera's size: a live scan decodes every frame into one DecodedFrame,
  // not into 100-200 MB of fresh memory the kernel must fault in and zero each time. On
  // failure `frame` is left in an unspecified but valid state.
  void decode(const std::vector<Image16u>& stack, DecodeOutputs outputs, DecodedFrame* frame);

  // A live scan's next stack, moved to the GPU ahead (CUDA; a CPU decoder does nothing): call
  // it on another thread while this decoder decodes, and the scan fuses, the frame before, so
  // that the upload (~11 ms at 12 MP) overlaps that work; the decode() of these same images
  // then takes the stack instead of uploading it (and waits for this upload if it is still
  // under way). The images must stay alive until then (the decode knows them by address); once
  // prefetch() has returned their pixels have been read (page-locked images too, which the copy
  // engine reads in place: it waits for that). One stack waits at a
  // time: a newer prefetch replaces it. Thread-safe against one decode() at a time on another
  // thread. Returns false when nothing was uploaded: a CPU decoder, a stack decode() would
  // refuse for its count or sizes (it then says why), or no upload slot to spare. Throws what
  // an upload throws (the GPU, pinned memory).
  bool prefetch(const std::vector<Image16u>& stack);

  const PatternSet& pattern_set() const;
  const DecodeOptions& options() const;
  const Device& device() const;
  const RayMap& rays() const;
  const DecodeParams& decode_params() const;
  const TriangulationParams& triangulation_params() const;
  // A CUDA decoder's last depth map, still on the GPU (an Image32f of MemoryType::kDevice, the
  // camera's size, 0 = invalid), valid until the next decode: the scan session integrates and
  // tracks from it without a second upload. nullptr for a CPU decoder.
  const Image32f* depth_on_device() const;
  // Its confidence map beside it (DecodedFrame::confidence), on the same terms.
  const Image32f* confidence_on_device() const;
  // The last decode's depth map into `depth_m` (sized to the camera): for a decode that left it
  // on the GPU (kDepthAndConfidenceOnDevice). A CPU decoder's is in its DecodedFrame already:
  // nothing to do. Throws sls::Error(kInvalidArgument) before any stack was decoded on the GPU.
  void download_depth(Image32f* depth_m);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct CloudOptions {
  // A neighbour is not used for the normal when its depth differs by more than
  // max_jump_pixels pixel footprints (z times the angle between neighbouring rays): a
  // surface steeper than atan(8) = 83 degrees to the view is treated as a discontinuity.
  double max_jump_pixels = 8.0;
  double min_confidence = 0.0;           // points below it are dropped
  bool keep_points_without_normal = false;  // isolated points: normal facing the camera
};

// Camera-frame points (depth * ray) of every valid pixel, with normals from the 4-neighbour
// differences (cross product of the horizontal and vertical central differences, one-sided
// where a neighbour is missing or across a depth discontinuity, oriented towards the
// camera) and, when given, the confidence. Throws sls::Error(kInvalidArgument) when sizes
// differ.
PointCloud depth_to_cloud(const Image32f& depth_m, const RayMap& rays, const Image32f* confidence = nullptr,
                          const CloudOptions& options = {});
PointCloud depth_to_cloud(const DecodedFrame& frame, const RayMap& rays, const CloudOptions& options = {});

}  // namespace sls
