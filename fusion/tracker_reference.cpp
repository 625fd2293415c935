// The Tracker's photometric reference frame: whether the photometric term runs for a frame,
// the reference kept from a tracked frame or given by the caller (set_reference_frame).
#include <cmath>
#include <optional>
#include <string>

#include "fusion/tracker_internal.h"

namespace sls::fusion {

using namespace tracking_detail;

std::optional<PhotometricSetup> Tracker::Impl::photometric_setup(bool have_texture, double live_mean,
                                                                 const Pose& T_world_model,
                                                                 std::string* skipped) const {
  if (!photometric_on) return std::nullopt;
  if (!have_texture) {
    *skipped = "no live texture";
    return std::nullopt;
  }
  if (!(live_mean > 0.0) || !std::isfinite(live_mean)) {
    *skipped = "the live texture is not positive over the depth pixels";
    return std::nullopt;
  }
  if (!reference_frame.valid) {
    *skipped = "no reference frame yet (this frame becomes it)";
    return std::nullopt;
  }
  PhotometricSetup setup;
  setup.T_model_ref = T_world_model.inverse() * reference_frame.T_world_camera;
  setup.live_mean = live_mean;
  setup.ref_mean = reference_frame.mean;
  return setup;
}

void Tracker::Impl::keep_reference(const float* const level_depth[8], const float* const level_texture[8],
                                   double mean, const Pose& T_world_camera) {
  reference_frame.depth.resize(levels.size());
  reference_frame.texture.resize(levels.size());
  for (std::size_t l = 0; l < levels.size(); ++l) {
    const std::size_t pixels = levels[l].pixels();
    reference_frame.depth[l].assign(level_depth[l], level_depth[l] + pixels);
    reference_frame.texture[l].assign(level_texture[l], level_texture[l] + pixels);
  }
  reference_frame.mean = mean;
  reference_frame.T_world_camera = T_world_camera;
  reference_frame.valid = true;
}

void Tracker::set_reference_frame(const Image32f& depth_m, const Image32f& texture, const Pose& T_world_camera) {
  Impl& s = *impl_;
  s.check_size(depth_m, "reference depth map");
  s.check_size(texture, "reference texture");
  if (!s.photometric_on) return;
  if (s.device.is_cuda()) {
    s.set_reference_gpu(depth_m, texture, T_world_camera);
    return;
  }
  s.check_on_host(depth_m, "reference depth map");
  s.check_on_host(texture, "reference texture");
  const float* level_depth[8] = {};
  const float* level_weight[8] = {};
  const float* level_texture[8] = {};
  s.depth_pyramid(depth_m.data(), nullptr, level_depth, level_weight, false);
  s.texture_pyramid(texture.data(), level_texture);
  const double mean = s.texture_mean(level_texture[0], level_depth[0]);
  if (!(mean > 0.0) || !std::isfinite(mean)) {
    s.reference_frame.valid = false;  // nothing to compare against: the term waits for the next one
    return;
  }
  s.keep_reference(level_depth, level_texture, mean, T_world_camera);
}

void Tracker::clear_reference_frame() { impl_->reference_frame.valid = false; }
bool Tracker::has_reference_frame() const { return impl_->reference_frame.valid; }

}  // namespace sls::fusion
