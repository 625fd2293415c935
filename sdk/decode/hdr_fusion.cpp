#include "sdk/decode/hdr_fusion.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <numeric>

#include "sdk/core/error.h"

namespace sls {

void HdrExposures::validate() const {
  if (scales.empty() || scales.size() > static_cast<std::size_t>(kHdrMaxExposures)) {
    throw_error(ErrorCode::kInvalidArgument, "HDR: {} exposures; 1 to {} are supported", scales.size(),
                kHdrMaxExposures);
  }
  for (std::size_t i = 0; i < scales.size(); ++i) {
    if (!(std::isfinite(scales[i]) && scales[i] > 0.0)) {
      throw_error(ErrorCode::kInvalidArgument, "HDR: exposure {} has scale {}; scales must be finite and positive", i,
                  scales[i]);
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (scales[j] == scales[i]) {
        throw_error(ErrorCode::kInvalidArgument, "HDR: exposures {} and {} both have scale {}", j, i, scales[i]);
      }
    }
  }
}

HdrExposures parse_hdr_exposures(const std::string& text) {
  HdrExposures exposures;
  exposures.scales.clear();
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const char* begin = item.c_str();
    char* end = nullptr;
    errno = 0;
    const double value = std::strtod(begin, &end);
    while (end != nullptr && (*end == ' ' || *end == '\t')) ++end;
    if (item.empty() || end == begin || *end != '\0' || errno == ERANGE) {
      throw_error(ErrorCode::kInvalidArgument, "HDR: exposures '{}': '{}' is not a number (expected e.g. 1,0.125)",
                  text, item);
    }
    exposures.scales.push_back(value);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  exposures.validate();
  return exposures;
}

namespace {

// The median ratio of the brightest samples above black of two exposures (see
// HdrFusionOptions), or NaN when too few pixels qualify.
double measured_ratio(const std::vector<std::uint16_t>& longer, const std::vector<std::uint16_t>& shorter,
                      float saturation_dn, double black_dn, double min_signal_dn, std::size_t min_pixels) {
  const std::size_t count = longer.size();
  const std::size_t stride = std::max<std::size_t>(1, count / 65536);  // ~64 k pixels are plenty
  std::vector<double> ratios;
  for (std::size_t i = 0; i < count; i += stride) {
    if (!(static_cast<float>(longer[i]) < saturation_dn) || !(static_cast<float>(shorter[i]) < saturation_dn)) continue;
    const double short_signal = static_cast<double>(shorter[i]) - black_dn;
    if (short_signal < min_signal_dn) continue;
    ratios.push_back((static_cast<double>(longer[i]) - black_dn) / short_signal);
  }
  if (ratios.size() < min_pixels) return std::nan("");
  auto middle = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
  std::nth_element(ratios.begin(), middle, ratios.end());
  return *middle;
}

}  // namespace

HdrFusedStack fuse_hdr_stack(const std::vector<Image16u>& images, std::size_t patterns, const HdrExposures& exposures,
                             const DecodeOptions& decode_options, const HdrFusionOptions& options) {
  exposures.validate();
  decode_options.validate();
  const std::size_t count = exposures.count();
  if (patterns == 0) throw_error(ErrorCode::kInvalidArgument, "HDR: a pattern set of no images");
  if (images.size() != patterns * count) {
    throw_error(ErrorCode::kInvalidArgument,
                "HDR: {} images for {} patterns at {} exposures (expected {}, the whole stack per exposure)",
                images.size(), patterns, count, patterns * count);
  }
  const int width = images.front().width(), height = images.front().height();
  for (std::size_t i = 0; i < images.size(); ++i) {
    if (images[i].empty() || images[i].width() != width || images[i].height() != height) {
      throw_error(ErrorCode::kInvalidArgument, "HDR: image {} (pattern {} of exposure {}) is {}x{}; image 0 is {}x{}",
                  i, i % patterns, i / patterns, images[i].width(), images[i].height(), width, height);
    }
  }
  const std::size_t pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  const float saturation = make_decode_thresholds(decode_options).saturation_dn;

  // Exposures longest first; each pixel's brightest sample per exposure.
  std::vector<std::size_t> order(count);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return exposures.scales[a] > exposures.scales[b]; });
  std::vector<std::vector<std::uint16_t>> peak(count, std::vector<std::uint16_t>(pixels, 0));
  for (std::size_t e = 0; e < count; ++e) {
    std::uint16_t* out = peak[e].data();
    for (std::size_t j = 0; j < patterns; ++j) {
      const std::uint16_t* in = images[order[e] * patterns + j].data();
      for (std::size_t i = 0; i < pixels; ++i) out[i] = std::max(out[i], in[i]);
    }
  }

  if (options.check_exposures) {
    const double full_scale = std::ldexp(1.0, decode_options.bit_depth) - 1.0;
    const double min_signal = options.min_check_signal_fraction * (full_scale - decode_options.black_level_dn);
    for (std::size_t e = 0; e + 1 < count; ++e) {
      const double measured = measured_ratio(peak[e], peak[e + 1], saturation, decode_options.black_level_dn,
                                             min_signal, options.min_check_pixels);
      const double expected = exposures.scales[order[e]] / exposures.scales[order[e + 1]];
      if (std::isfinite(measured) && std::abs(measured / expected - 1.0) > options.max_ratio_error) {
        throw_error(ErrorCode::kFormat,
                    "HDR: exposure {} (scale {}) is {:.3g}x as bright as exposure {} (scale {}) on the median pixel; "
                    "the scales say {:.3g}x (did the camera apply the exposure? are the stacks in order?)",
                    order[e], exposures.scales[order[e]], measured, order[e + 1], exposures.scales[order[e + 1]],
                    expected);
      }
    }
  }

  HdrFusedStack fused;
  fused.exposure_index = Image8u(width, height);
  fused.images.reserve(patterns);
  for (std::size_t j = 0; j < patterns; ++j) fused.images.emplace_back(width, height);
  std::uint16_t pixel_peaks[kHdrMaxExposures];
  for (std::size_t i = 0; i < pixels; ++i) {
    for (std::size_t e = 0; e < count; ++e) pixel_peaks[e] = peak[e][i];
    const int picked = hdr_pick_exposure(pixel_peaks, static_cast<int>(count), saturation);
    if (!(static_cast<float>(pixel_peaks[picked]) < saturation)) ++fused.saturated_pixels;
    const std::size_t source = order[static_cast<std::size_t>(picked)];
    fused.exposure_index.data()[i] = static_cast<std::uint8_t>(source);
    for (std::size_t j = 0; j < patterns; ++j) fused.images[j].data()[i] = images[source * patterns + j].data()[i];
  }
  return fused;
}

Image32f hdr_texture(const HdrFusedStack& fused, const HdrExposures& exposures, const DecodeLayout& layout,
                     double black_level_dn) {
  exposures.validate();
  const auto index = [&](int i) { return i >= 0 && static_cast<std::size_t>(i) < fused.images.size(); };
  if (!index(layout.white_index)) return {};
  const Image16u& white = fused.images[static_cast<std::size_t>(layout.white_index)];
  const Image16u* black = index(layout.black_index) ? &fused.images[static_cast<std::size_t>(layout.black_index)] : nullptr;
  const double longest = *std::max_element(exposures.scales.begin(), exposures.scales.end());
  double gain[kHdrMaxExposures];
  for (std::size_t e = 0; e < exposures.count(); ++e) gain[e] = longest / exposures.scales[e];
  Image32f texture(white.width(), white.height(), 0.0f);
  for (std::size_t i = 0; i < white.pixel_count(); ++i) {
    const double dark = black != nullptr ? static_cast<double>(black->data()[i]) : black_level_dn;
    const std::size_t e = std::min<std::size_t>(fused.exposure_index.data()[i], exposures.count() - 1);
    texture.data()[i] = static_cast<float>((static_cast<double>(white.data()[i]) - dark) * gain[e]);
  }
  return texture;
}

}  // namespace sls
