#include "fusion/volume.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>

#include "sdk/core/buffer.h"
#include "sdk/core/device_memory.h"
#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"

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
  // The voxels, where the volume lives (host memory, or the GPU's); a format's arrays only.
  Buffer<float> u32, w32, a32;
  Buffer<std::uint16_t> u16, a16;
  Buffer<std::uint8_t> w8;
  Buffer<std::uint8_t> bricks;  // VolumeView::surface_bricks
  MemoryType memory() const { return device.is_cuda() ? MemoryType::kDevice : MemoryType::kHost; }
  std::size_t brick_count() const {
    VolumeView v;
    v.nx = geometry.nx;
    v.ny = geometry.ny;
    v.nz = geometry.nz;
    return v.brick_count();
  }
};

namespace {

// `count` zeros where `memory` says (the GPU's memory: set before returning).
template <typename T>
void allocate(Buffer<T>* buffer, std::size_t count, MemoryType memory, const VolumeGeometry& g, VoxelFormat format,
              AverageStorage average) {
  try {
    buffer->assign(count, T{}, memory);
  } catch (const std::bad_alloc&) {
    throw_error(ErrorCode::kOutOfMemory, "volume {} x {} x {} ({}, {:.1f} MiB) does not fit in host memory", g.nx,
                g.ny, g.nz, voxel_format_name(format),
                static_cast<double>(count * bytes_per_voxel(format, average)) / 1048576.0);
  }
}

// Zeros, in place. On the GPU before returning: the kernels that touch the volume next run on
// the session's non-blocking streams, which would not wait for the clear (seen: a reused
// allocation's old voxels wiping a frame).
template <typename T>
void zero(Buffer<T>& buffer) {
  if (buffer.memory_type() == MemoryType::kDevice) {
    zero_device(buffer.data(), buffer.size_bytes());
  } else {
    std::fill(buffer.data(), buffer.data() + buffer.size(), T{});
  }
}

template <typename T>
T* data_or_null(Buffer<T>& buffer) {
  return buffer.empty() ? nullptr : buffer.data();
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
  const std::size_t needed = count * bytes_per_voxel(format, average);
  // Say what does not fit before trying: the volume is the one big allocation. (On the host,
  // with overcommit, an allocation too large for the machine "succeeds" and the process is
  // killed later, without a word.)
  if (!device.is_cuda()) {
    admit_host_allocation(needed,
                          fmt::format("volume {} x {} x {} ({}{})", geometry.nx, geometry.ny, geometry.nz,
                                      voxel_format_name(format), separate ? " with GTSDF's running average" : ""),
                          format == VoxelFormat::kFloat32 ? "use fewer or larger voxels, or the compact format"
                                                          : "use fewer or larger voxels");
  } else {
    const GpuMemory gpu = gpu_memory(device);  // throws kUnsupported: CUDA asked of a build without it
    const std::size_t free_bytes = gpu.total_bytes - std::min(gpu.used_bytes, gpu.total_bytes);
    if (needed > free_bytes) {
      throw_error(ErrorCode::kOutOfMemory,
                  "volume {} x {} x {} ({}{}, {} B/voxel) needs {:.1f} MiB of GPU memory; {:.1f} MiB of {:.1f} MiB "
                  "are free: use fewer voxels or the compact format",
                  geometry.nx, geometry.ny, geometry.nz, voxel_format_name(format),
                  separate ? " with GTSDF's running average" : "", bytes_per_voxel(format, average),
                  static_cast<double>(needed) / 1048576.0, static_cast<double>(free_bytes) / 1048576.0,
                  static_cast<double>(gpu.total_bytes) / 1048576.0);
    }
  }
  Impl& s = *impl_;
  const MemoryType memory = s.memory();
  if (format == VoxelFormat::kFloat32) {
    allocate(&s.u32, count, memory, geometry, format, average);
    allocate(&s.w32, count, memory, geometry, format, average);
    if (separate) allocate(&s.a32, count, memory, geometry, format, average);
  } else {
    allocate(&s.u16, count, memory, geometry, format, average);
    allocate(&s.w8, count, memory, geometry, format, average);
    if (separate) allocate(&s.a16, count, memory, geometry, format, average);
  }
  allocate(&s.bricks, s.brick_count(), memory, geometry, format, average);
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
  if (s.device.is_cuda()) require_device(s.device);
  zero(s.u32);
  zero(s.w32);
  zero(s.a32);
  zero(s.u16);
  zero(s.a16);
  zero(s.w8);
  zero(s.bricks);
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
  v.u32 = data_or_null(s.u32);
  v.w32 = data_or_null(s.w32);
  v.u16 = data_or_null(s.u16);
  v.w8 = data_or_null(s.w8);
  v.a32 = data_or_null(s.a32);
  v.a16 = data_or_null(s.a16);
  v.surface_bricks = data_or_null(s.bricks);
  return v;
}

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
  // Host to host, or through the GPU's driver (which tells host from device pointers), before
  // returning: the kernels that read the volume next run on non-blocking streams.
  const bool device_involved = device().is_cuda() || other.device().is_cuda();
  const auto copy = [device_involved](void* into, const void* values, std::size_t bytes) {
    if (values != nullptr) copy_memory(into, values, bytes, device_involved);
  };
  if (format() == VoxelFormat::kFloat32) {
    copy(to.u32, from.u32, count * sizeof(float));
    copy(to.w32, from.w32, count * sizeof(float));
    copy(to.a32, from.a32, count * sizeof(float));
  } else {
    copy(to.u16, from.u16, count * sizeof(std::uint16_t));
    copy(to.w8, from.w8, count);
    copy(to.a16, from.a16, count * sizeof(std::uint16_t));
  }
  copy(to.surface_bricks, from.surface_bricks, from.brick_count());
}

Volume Volume::to_host() const {
  Volume host(impl_->geometry, impl_->format, Device::cpu(), impl_->average);
  host.copy_from(*this);
  return host;
}

}  // namespace sls::fusion
