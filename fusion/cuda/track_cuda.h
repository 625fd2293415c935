// Internal: the CUDA launchers of the ICP tracker (fusion/tracker.h) around track_shared.h.
// Only built and included when SLS_HAVE_CUDA is defined; free of Eigen.
//
// Reductions are two-stage and deterministic: each block of kTrackThreads threads sums its
// pixels in float (per thread, then warp shuffles, then shared memory across the warps) and
// writes its sums as doubles to `partials` (at most kTrackMaxBlocks blocks x the number of
// sums, a grid-stride loop covers larger images); a second kernel adds the blocks' partials
// in double, in block order, into `out`.
#pragma once

#include <cstdint>

#include <cuda_runtime_api.h>

#include "fusion/photometric_shared.h"
#include "fusion/track_shared.h"

namespace sls::fusion::detail {

constexpr int kTrackThreads = 256;
constexpr int kTrackMaxBlocks = 512;
// Doubles `partials` must hold.
constexpr int kTrackPartials = kTrackMaxBlocks * kTrackSums;

// Level l + 1 of the live pyramid from level l (downsample_depth per coarse pixel), and of its
// weight map when fine_weight and coarse_weight are given (both, or neither).
void launch_downsample_depth_cuda(const float* fine, const float* fine_weight, int fine_width, int fine_height,
                                  float fine_fx, float* coarse, float* coarse_weight, int coarse_width,
                                  int coarse_height, cudaStream_t stream);
// live_normal per pixel of a level.
void launch_live_normals_cuda(const float* depth, const Vec3f* rays, int width, int height, float fx,
                              float baseline_m, Vec3f* normals, cudaStream_t stream);
// The crease test on the model maps (width x height): baseline_normal per pixel into
// `normals`, then near_crease per pixel into `mask`.
void launch_model_creases_cuda(const Vec3f* points, int width, int height, float fx, float baseline_m,
                               float radius_m, float min_cos, Vec3f* normals, std::uint8_t* mask,
                               cudaStream_t stream);
// accumulate_frame_statistics over `pixels` pixels (model points, live depth and rays of the
// finest level) into out[kFrameSums].
void launch_frame_statistics_cuda(const Vec3f* model_points, const float* live_depth, const Vec3f* live_rays,
                                  const TrackRegion& region, int pixels, Vec3f reference, double* partials,
                                  double* out, cudaStream_t stream);
// One Gauss–Newton step's sums (track_pixel + accumulate_track_row over the live level) into
// out[kTrackSums].
void launch_track_cuda(const TrackLiveView& live, const TrackModelView& model, const TrackParams& params,
                       double* partials, double* out, cudaStream_t stream);

// The photometric term (photometric_shared.h). `partials` holds kTrackMaxBlocks *
// kPhotometricSums doubles.
// Level l + 1 of a texture pyramid from level l (downsample_texture per coarse pixel).
void launch_downsample_texture_cuda(const float* fine, int fine_width, int fine_height, float* coarse,
                                    int coarse_width, int coarse_height, cudaStream_t stream);
// accumulate_texture_statistics over `pixels` pixels into out[kTextureSums].
void launch_texture_statistics_cuda(const float* texture, const float* depth, int pixels, double* partials,
                                    double* out, cudaStream_t stream);
// One Gauss–Newton step's photometric sums (photometric_pixel + accumulate_photometric over
// the reference level) into out[kPhotometricSums].
void launch_photometric_cuda(const PhotometricLevelView& reference, const PhotometricLevelView& live,
                             const PhotometricParams& params, double* partials, double* out, cudaStream_t stream);

}  // namespace sls::fusion::detail
