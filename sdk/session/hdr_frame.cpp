#include "sdk/session/hdr_frame.h"

#include <utility>

#include "sdk/decode/hdr_fusion.h"
#include "sdk/decode/pattern_set.h"

namespace sls::session {

void fuse_hdr_frame(const RecordingInfo& info, const DecodeOptions& decode, ScanFrame* frame) {
  if (info.exposures.size() < 2) return;
  const PatternSet set = pattern_set_from_json(info.pattern_set_json);
  const HdrExposures exposures{info.exposures};
  HdrFusedStack fused = fuse_hdr_stack(frame->pattern_images(), set.size(), exposures, decode);
  if (!frame->texture) {
    Image32f texture = hdr_texture(fused, exposures, make_decode_layout(set), decode.black_level_dn);
    if (!texture.empty()) frame->texture = std::move(texture);
  }
  frame->images = std::move(fused.images);
  frame->shared_images.reset();  // the exposures' stack stays with the recording's writer alone
}

DecodeOptions hdr_decode_options(const RecordingInfo& info) {
  DecodeOptions decode;
  decode.bit_depth = info.camera.bit_depth;
  return decode;
}

}  // namespace sls::session
