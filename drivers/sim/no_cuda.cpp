// The simulator's CUDA renderer in a build without CUDA (sim/render_backend.h): it links, and
// asking for it throws kUnsupported.
#include "drivers/sim/render_backend.h"
#include "sdk/core/error.h"

namespace sls::sim {

std::unique_ptr<RenderBackend> make_cuda_render_backend(const RayMap&, int device_id) {
  throw_error(ErrorCode::kUnsupported, "the simulator's renderer on cuda:{}: this build has no CUDA support", device_id);
}

}  // namespace sls::sim
