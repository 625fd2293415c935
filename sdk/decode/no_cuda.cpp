// The decoder's GPU half in a build without CUDA (sdk/decode/decoder_gpu.h): it links, and
// making one throws kUnsupported. (Never reached: a decoder on a GPU is refused first, by
// require_device.)
#include "sdk/core/error.h"
#include "sdk/decode/decoder_gpu.h"

namespace sls::detail {
namespace {

[[noreturn]] void no_cuda() { throw_error(ErrorCode::kUnsupported, "decode on a GPU: this build has no CUDA support"); }

}  // namespace

struct DecoderGpu::State {};

DecoderGpu::DecoderGpu(const DecodeParams&, const TriangulationParams&, std::shared_ptr<const SharedRayMap>,
                                     const GpuStream&, const GpuStream&)
    : state_(nullptr) {
  no_cuda();
}
DecoderGpu::~DecoderGpu() = default;
bool DecoderGpu::prefetch(const std::uint16_t* const*) { no_cuda(); }
int DecoderGpu::take_prefetched(const std::uint16_t* const*) { no_cuda(); }
int DecoderGpu::upload_async(const std::uint16_t* const*) { no_cuda(); }
void DecoderGpu::decode_slot(int) { no_cuda(); }
void DecoderGpu::gather_check_async(int, const StackCheckGrid&, const StackCheckPlan&) { no_cuda(); }
StackCheckInputs DecoderGpu::wait_check() { no_cuda(); }
void DecoderGpu::queue_landing(bool, bool) { no_cuda(); }
void DecoderGpu::download(const DecodeOutputsHost&) { no_cuda(); }
void DecoderGpu::synchronize() { no_cuda(); }
const Image32f& DecoderGpu::depth_image() const { no_cuda(); }
const Image32f& DecoderGpu::confidence_image() const { no_cuda(); }

}  // namespace sls::detail
