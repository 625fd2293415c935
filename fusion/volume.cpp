#include "fusion/volume.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>
#include <vector>

#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>

#include "sdk/core/cuda/device_buffer.h"
#endif

namespace sls::fusion {

std::size_t VolumeGeometry::voxel_count() const {
  return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny) * static_cast<std::size_t>(nz);
}

Eigen::Vector3d VolumeGeometry::size_m() const {
  return Eigen::Vector3d(nx, ny, nz) * voxel_size_m;
}

VolumeGeometry VolumeGeometry::centred(const Eigen::Vector3d& centre_world, int nx, int ny, int nz,
                                       double voxel_size_m) {
  VolumeGeometry g;
  g.nx = nx;
  g.ny = ny;
  g.nz = nz;
  g.voxel_size_m = voxel_size_m;
  g.T_world_volume = Pose(Eigen::Matrix3d::Identity(), centre_world - 0.5 * g.size_m());
  return g;
}

void VolumeGeometry::validate() const {
  if (nx < 2 || ny < 2 || nz < 2) {
    throw_error(ErrorCode::kInvalidArgument, "volume: {} x {} x {} voxels: each axis needs at least 2", nx, ny, nz);
  }
  if (nz > 65535) {  // one CUDA grid layer per z slice
    throw_error(ErrorCode::kInvalidArgument, "volume: {} voxels along z, at most 65535", nz);
  }
  if (voxel_count() > std::size_t{std::numeric_limits<std::uint32_t>::max()}) {
    throw_error(ErrorCode::kInvalidArgument, "volume: {} x {} x {} = {} voxels, more than 2^32", nx, ny, nz,
                voxel_count());
  }
  if (!(voxel_size_m > 0.0) || !std::isfinite(voxel_size_m)) {
    throw_error(ErrorCode::kInvalidArgument, "volume: voxel size {} m is not positive and finite", voxel_size_m);
  }
}

std::size_t bytes_per_voxel(VoxelFormat format, AverageStorage average) {
  return voxel_bytes(format, average == AverageStorage::kSeparate);
}

const char* voxel_format_name(VoxelFormat format) {
  return format == VoxelFormat::kFloat32 ? "float32" : "compact";
}

VoxelFormat parse_voxel_format(const std::string& name) {
  if (name == "float32") return VoxelFormat::kFloat32;
  if (name == "compact") return VoxelFormat::kCompact;
  throw_error(ErrorCode::kInvalidArgument, "unknown voxel format '{}' (float32 or compact)", name);
}

void set_view_pose(VolumeView* view, const Pose& T_world_volume) {
  view->T_world_volume = T_world_volume.to_rigid3f();
  view->T_volume_world = T_world_volume.inverse().to_rigid3f();
}

struct Volume::Impl {
  VolumeGeometry geometry;
  VoxelFormat format = VoxelFormat::kFloat32;
  AverageStorage average = AverageStorage::kInU;
  Device device;
  // CPU storage.
  std::vector<float> u32, w32, a32;
  std::vector<std::uint16_t> u16, a16;
  std::vector<std::uint8_t> w8;
  std::vector<std::uint8_t> bricks;  // VolumeView::surface_bricks
#if defined(SLS_HAVE_CUDA)
  DeviceBuffer<float> device_u32, device_w32, device_a32;
  DeviceBuffer<std::uint16_t> device_u16, device_a16;
  DeviceBuffer<std::uint8_t> device_w8;
  DeviceBuffer<std::uint8_t> device_bricks;
#endif
  std::size_t brick_count() const {
    VolumeView v;
    v.nx = geometry.nx;
    v.ny = geometry.ny;
    v.nz = geometry.nz;
    return v.brick_count();
  }
};

namespace {

template <typename T>
void allocate_host(std::vector<T>* buffer, std::size_t count, const VolumeGeometry& g, VoxelFormat format,
                   AverageStorage average) {
  try {
    buffer->assign(count, T{});
  } catch (const std::bad_alloc&) {
    throw_error(ErrorCode::kOutOfMemory, "volume {} x {} x {} ({}, {:.1f} MiB) does not fit in host memory", g.nx,
                g.ny, g.nz, voxel_format_name(format),
                static_cast<double>(count * bytes_per_voxel(format, average)) / 1048576.0);
  }
}

}  // namespace

Volume::Volume(const VolumeGeometry& geometry, VoxelFormat format, const Device& device, AverageStorage average)
    : impl_(std::make_unique<Impl>()) {
  geometry.validate();
  impl_->geometry = geometry;
  impl_->format = format;
  impl_->average = average;
  impl_->device = device;
  const std::size_t count = geometry.voxel_count();
  const bool separate = average == AverageStorage::kSeparate;
  if (!device.is_cuda()) {
    // Say what does not fit before trying: with overcommit, an allocation too large for the
    // machine "succeeds" and the process is killed later, without a word.
    admit_host_allocation(count * bytes_per_voxel(format, average),
                          fmt::format("volume {} x {} x {} ({}{})", geometry.nx, geometry.ny, geometry.nz,
                                      voxel_format_name(format), separate ? " with GTSDF's running average" : ""),
                          format == VoxelFormat::kFloat32 ? "use fewer or larger voxels, or the compact format"
                                                          : "use fewer or larger voxels");
    if (format == VoxelFormat::kFloat32) {
      allocate_host(&impl_->u32, count, geometry, format, average);
      allocate_host(&impl_->w32, count, geometry, format, average);
      if (separate) allocate_host(&impl_->a32, count, geometry, format, average);
    } else {
      allocate_host(&impl_->u16, count, geometry, format, average);
      allocate_host(&impl_->w8, count, geometry, format, average);
      if (separate) allocate_host(&impl_->a16, count, geometry, format, average);
    }
    allocate_host(&impl_->bricks, impl_->brick_count(), geometry, format, average);
    return;
  }
#if defined(SLS_HAVE_CUDA)
  require_device(device);
  // Say what does not fit before trying: the volume is the one big allocation.
  std::size_t free_bytes = 0, total_bytes = 0;
  SLS_CUDA_CHECK(cudaMemGetInfo(&free_bytes, &total_bytes));
  const std::size_t needed = count * bytes_per_voxel(format, average);
  if (needed > free_bytes) {
    throw_error(ErrorCode::kOutOfMemory,
                "volume {} x {} x {} ({}{}, {} B/voxel) needs {:.1f} MiB of GPU memory; {:.1f} MiB of {:.1f} MiB are "
                "free: use fewer voxels or the compact format",
                geometry.nx, geometry.ny, geometry.nz, voxel_format_name(format),
                separate ? " with GTSDF's running average" : "", bytes_per_voxel(format, average),
                static_cast<double>(needed) / 1048576.0, static_cast<double>(free_bytes) / 1048576.0,
                static_cast<double>(total_bytes) / 1048576.0);
  }
  if (format == VoxelFormat::kFloat32) {
    impl_->device_u32.allocate(count);
    impl_->device_w32.allocate(count);
    if (separate) impl_->device_a32.allocate(count);
  } else {
    impl_->device_u16.allocate(count);
    impl_->device_w8.allocate(count);
    if (separate) impl_->device_a16.allocate(count);
  }
  impl_->device_bricks.allocate(impl_->brick_count());
  clear();
#else
  require_device(device);  // throws kUnsupported: CUDA asked of a build without it
#endif
}

Volume::~Volume() = default;
Volume::Volume(Volume&&) noexcept = default;
Volume& Volume::operator=(Volume&&) noexcept = default;

const VolumeGeometry& Volume::geometry() const { return impl_->geometry; }
VoxelFormat Volume::format() const { return impl_->format; }
AverageStorage Volume::average_storage() const { return impl_->average; }
const Device& Volume::device() const { return impl_->device; }
std::size_t Volume::bytes() const {
  return impl_->geometry.voxel_count() * bytes_per_voxel(impl_->format, impl_->average);
}

void Volume::clear() {
  // U = 0 with W = 0: an unobserved voxel's U is never read as a value (0 keeps the first
  // running average (0 * U + f) / 1 finite).
  Impl& s = *impl_;
  if (!s.device.is_cuda()) {
    std::fill(s.u32.begin(), s.u32.end(), 0.0f);
    std::fill(s.w32.begin(), s.w32.end(), 0.0f);
    std::fill(s.a32.begin(), s.a32.end(), 0.0f);
    std::fill(s.u16.begin(), s.u16.end(), std::uint16_t{0});
    std::fill(s.a16.begin(), s.a16.end(), std::uint16_t{0});
    std::fill(s.w8.begin(), s.w8.end(), std::uint8_t{0});
    std::fill(s.bricks.begin(), s.bricks.end(), std::uint8_t{0});
    return;
  }
#if defined(SLS_HAVE_CUDA)
  require_device(s.device);
  if (s.device_u32.size() > 0) SLS_CUDA_CHECK(cudaMemset(s.device_u32.data(), 0, s.device_u32.size_bytes()));
  if (s.device_w32.size() > 0) SLS_CUDA_CHECK(cudaMemset(s.device_w32.data(), 0, s.device_w32.size_bytes()));
  if (s.device_a32.size() > 0) SLS_CUDA_CHECK(cudaMemset(s.device_a32.data(), 0, s.device_a32.size_bytes()));
  if (s.device_u16.size() > 0) SLS_CUDA_CHECK(cudaMemset(s.device_u16.data(), 0, s.device_u16.size_bytes()));
  if (s.device_a16.size() > 0) SLS_CUDA_CHECK(cudaMemset(s.device_a16.data(), 0, s.device_a16.size_bytes()));
  if (s.device_w8.size() > 0) SLS_CUDA_CHECK(cudaMemset(s.device_w8.data(), 0, s.device_w8.size_bytes()));
  SLS_CUDA_CHECK(cudaMemset(s.device_bricks.data(), 0, s.device_bricks.size_bytes()));
  // cudaMemset returns before device memory is set, on the legacy stream, which the
  // integrator's and raycaster's non-blocking streams do not wait for: without this the next
  // integration can race the clear (seen: a reused allocation's old voxels wiping a frame).
  SLS_CUDA_CHECK(cudaStreamSynchronize(nullptr));
#endif
}

void Volume::set_pose(const Pose& T_world_volume) { impl_->geometry.T_world_volume = T_world_volume; }

VolumeView Volume::view() const {
  Impl& s = *impl_;
  VolumeView v;
  v.nx = s.geometry.nx;
  v.ny = s.geometry.ny;
  v.nz = s.geometry.nz;
  v.voxel_size_m = static_cast<float>(s.geometry.voxel_size_m);
  set_view_pose(&v, s.geometry.T_world_volume);
  v.format = s.format;
  if (!s.device.is_cuda()) {
    v.u32 = s.u32.empty() ? nullptr : s.u32.data();
    v.w32 = s.w32.empty() ? nullptr : s.w32.data();
    v.u16 = s.u16.empty() ? nullptr : s.u16.data();
    v.w8 = s.w8.empty() ? nullptr : s.w8.data();
    v.a32 = s.a32.empty() ? nullptr : s.a32.data();
    v.a16 = s.a16.empty() ? nullptr : s.a16.data();
    v.surface_bricks = s.bricks.data();
    return v;
  }
#if defined(SLS_HAVE_CUDA)
  v.u32 = s.device_u32.data();
  v.w32 = s.device_w32.data();
  v.u16 = s.device_u16.data();
  v.w8 = s.device_w8.data();
  v.a32 = s.device_a32.size() > 0 ? s.device_a32.data() : nullptr;
  v.a16 = s.device_a16.size() > 0 ? s.device_a16.data() : nullptr;
  v.surface_bricks = s.device_bricks.data();
#endif
  return v;
}

namespace {

#if defined(SLS_HAVE_CUDA)
// Returns once the bytes are there: a device-to-device cudaMemcpy may return before the copy
// is done, and the kernels that read the volume next run on non-blocking streams.
void copy_bytes(void* to, const void* from, std::size_t bytes) {
  if (bytes > 0) SLS_CUDA_CHECK(cudaMemcpy(to, from, bytes, cudaMemcpyDefault));
  SLS_CUDA_CHECK(cudaStreamSynchronize(nullptr));
}
#endif

}  // namespace

void Volume::copy_from(const Volume& other) {
  const VolumeGeometry& a = impl_->geometry;
  const VolumeGeometry& b = other.geometry();
  if (a.nx != b.nx || a.ny != b.ny || a.nz != b.nz || a.voxel_size_m != b.voxel_size_m || format() != other.format() ||
      average_storage() != other.average_storage()) {
    const auto average_name = [](AverageStorage storage) {
      return storage == AverageStorage::kSeparate ? " with running average" : "";
    };
    throw_error(ErrorCode::kInvalidArgument, "volume copy: {} x {} x {} {}{} into {} x {} x {} {}{}", b.nx, b.ny, b.nz,
                voxel_format_name(other.format()), average_name(other.average_storage()), a.nx, a.ny, a.nz,
                voxel_format_name(format()), average_name(average_storage()));
  }
  const VolumeView to = view();
  const VolumeView from = other.view();
  const std::size_t count = a.voxel_count();
  const bool both_cpu = !device().is_cuda() && !other.device().is_cuda();
  if (both_cpu) {
    if (format() == VoxelFormat::kFloat32) {
      std::copy(from.u32, from.u32 + count, to.u32);
      std::copy(from.w32, from.w32 + count, to.w32);
      if (from.a32 != nullptr) std::copy(from.a32, from.a32 + count, to.a32);
    } else {
      std::copy(from.u16, from.u16 + count, to.u16);
      std::copy(from.w8, from.w8 + count, to.w8);
      if (from.a16 != nullptr) std::copy(from.a16, from.a16 + count, to.a16);
    }
    std::copy(from.surface_bricks, from.surface_bricks + from.brick_count(), to.surface_bricks);
    return;
  }
#if defined(SLS_HAVE_CUDA)
  // cudaMemcpyDefault: unified addressing tells host from device pointers.
  if (format() == VoxelFormat::kFloat32) {
    copy_bytes(to.u32, from.u32, count * sizeof(float));
    copy_bytes(to.w32, from.w32, count * sizeof(float));
    if (from.a32 != nullptr) copy_bytes(to.a32, from.a32, count * sizeof(float));
  } else {
    copy_bytes(to.u16, from.u16, count * sizeof(std::uint16_t));
    copy_bytes(to.w8, from.w8, count);
    if (from.a16 != nullptr) copy_bytes(to.a16, from.a16, count * sizeof(std::uint16_t));
  }
  copy_bytes(to.surface_bricks, from.surface_bricks, from.brick_count());
#endif
}

Volume Volume::to_host() const {
  Volume host(impl_->geometry, impl_->format, Device::cpu(), impl_->average);
  host.copy_from(*this);
  return host;
}

}  // namespace sls::fusion
