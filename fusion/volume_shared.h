// The Rectangular Parallelepiped Volume's voxels as the per-voxel code of both backends sees
// them (DESIGN.md sections 3 and 6): a plain view over the U (truncated signed distance in
// units of the truncation δ, in [-1, 1]) and W (weight) arrays, in one of two formats:
//   kFloat32  U float, W float            8 B/voxel  (reference, tests)
//   kCompact  U IEEE binary16, W uint8    3 B/voxel  (960³ = 2.6 GB: the production format)
// A GTSDF volume also keeps A, the plain running average of the frames' truncated distances
// (the data term of the paper's functional (2)), in U's type: +4 or +2 B/voxel. Without it
// (TSDF) U is A.
// Arrays are structure-of-arrays, x fastest, so neighbouring threads touch neighbouring bytes.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

#if defined(__CUDACC__)
#include <cuda_fp16.h>
#endif

namespace sls::fusion {

enum class VoxelFormat : std::int32_t {
  kFloat32 = 0,
  kCompact = 1,
};

// float <-> IEEE binary16 (round to nearest even), the compact format's U and A. The
// definition is written once in integer arithmetic (float_to_half_bits, half_to_float_bits),
// so that the CPU and the GPU hold the same bits without cuda_fp16.h on the host. On the GPU
// float_to_half and half_to_float are the hardware's conversions instead, one instruction
// each against 10-25 (the raycast reads 8 corners a sample, the resample 24 values a voxel):
// the same bits for every finite and infinite value (IEEE rounding); a NaN, which no volume
// should hold, takes the definition's path, so that even its bits agree
// (test_half_cuda checks all 2^32 floats and 2^16 halves on the GPU).
SLS_HOST_DEVICE inline std::uint32_t float_bits(float value) {
#if defined(__CUDA_ARCH__)
  return __float_as_uint(value);
#else
  std::uint32_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  return bits;
#endif
}

SLS_HOST_DEVICE inline float bits_float(std::uint32_t bits) {
#if defined(__CUDA_ARCH__)
  return __uint_as_float(bits);
#else
  float value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
#endif
}

SLS_HOST_DEVICE inline std::uint16_t float_to_half_bits(float value) {
  const std::uint32_t x = float_bits(value);
  const std::uint32_t sign = (x >> 16) & 0x8000u;
  std::uint32_t mantissa = x & 0x7fffffu;
  const int exponent = static_cast<int>((x >> 23) & 0xffu);
  if (exponent == 255) return static_cast<std::uint16_t>(sign | 0x7c00u | (mantissa != 0u ? 0x200u : 0u));
  const int e = exponent - 127 + 15;
  if (e >= 31) return static_cast<std::uint16_t>(sign | 0x7c00u);  // overflow: infinity
  if (e <= 0) {                                                    // subnormal or zero
    if (e < -10) return static_cast<std::uint16_t>(sign);
    mantissa |= 0x800000u;
    const int shift = 14 - e;
    std::uint32_t half_mantissa = mantissa >> shift;
    const std::uint32_t remainder = mantissa & ((1u << shift) - 1u);
    const std::uint32_t halfway = 1u << (shift - 1);
    if (remainder > halfway || (remainder == halfway && (half_mantissa & 1u) != 0u)) ++half_mantissa;
    return static_cast<std::uint16_t>(sign | half_mantissa);
  }
  std::uint32_t half = sign | (static_cast<std::uint32_t>(e) << 10) | (mantissa >> 13);
  const std::uint32_t remainder = mantissa & 0x1fffu;
  if (remainder > 0x1000u || (remainder == 0x1000u && (half & 1u) != 0u)) ++half;  // a carry rounds up the exponent
  return static_cast<std::uint16_t>(half);
}

SLS_HOST_DEVICE inline float half_to_float_bits(std::uint16_t half) {
  const std::uint32_t sign = static_cast<std::uint32_t>(half & 0x8000u) << 16;
  const std::uint32_t exponent = (half >> 10) & 0x1fu;
  const std::uint32_t mantissa = half & 0x3ffu;
  if (exponent == 0u) {
    const float magnitude = static_cast<float>(mantissa) * 5.9604644775390625e-8f;  // 2^-24, exact
    return sign != 0u ? -magnitude : magnitude;
  }
  if (exponent == 31u) return bits_float(sign | 0x7f800000u | (mantissa << 13));
  return bits_float(sign | ((exponent - 15u + 127u) << 23) | (mantissa << 13));
}

SLS_HOST_DEVICE inline std::uint16_t float_to_half(float value) {
#if defined(__CUDA_ARCH__)
  if (value != value) return float_to_half_bits(value);
  return __half_as_ushort(__float2half_rn(value));
#else
  return float_to_half_bits(value);
#endif
}

SLS_HOST_DEVICE inline float half_to_float(std::uint16_t half) {
#if defined(__CUDA_ARCH__)
  if ((half & 0x7fffu) > 0x7c00u) return half_to_float_bits(half);
  return __half2float(__ushort_as_half(half));
#else
  return half_to_float_bits(half);
#endif
}

// Bytes a voxel takes: U and W, and GTSDF's running average A where the volume keeps it apart.
SLS_HOST_DEVICE inline std::size_t voxel_bytes(VoxelFormat format, bool separate_average) {
  const std::size_t u_bytes = format == VoxelFormat::kFloat32 ? 4u : 2u;
  const std::size_t w_bytes = format == VoxelFormat::kFloat32 ? 4u : 1u;
  return u_bytes + w_bytes + (separate_average ? u_bytes : 0u);
}

// The volume as kernels see it. Voxel (i, j, k) has its centre at ((i, j, k) + 0.5) *
// voxel_size_m in the volume frame; T_world_volume places the volume (rotation included).
struct VolumeView {
  int nx = 0, ny = 0, nz = 0;
  float voxel_size_m = 0.0f;
  Rigid3f T_world_volume{};
  Rigid3f T_volume_world{};
  VoxelFormat format = VoxelFormat::kFloat32;
  float* u32 = nullptr;            // kFloat32
  float* w32 = nullptr;
  std::uint16_t* u16 = nullptr;    // kCompact
  std::uint8_t* w8 = nullptr;
  float* a32 = nullptr;            // A, when the volume keeps it (kFloat32)
  std::uint16_t* a16 = nullptr;    // A, when the volume keeps it (kCompact)
  // One flag per brick of kBrick³ voxels, set once a voxel within one voxel of the brick has
  // been observed with |U| < 1 (never cleared until the volume is): where it is 0 there is no
  // surface, and a raycast jumps the whole brick. nullptr: no flags (every brick may hold one).
  std::uint8_t* surface_bricks = nullptr;
  static constexpr int kBrickShift = 3;  // 8 voxels a side

  SLS_HOST_DEVICE std::size_t voxel_count() const {
    return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny) * static_cast<std::size_t>(nz);
  }
  // In 32-bit arithmetic, widened: a volume holds at most 2^32 voxels (volume.cpp), and the
  // GPU's 64-bit multiplies are several instructions each.
  SLS_HOST_DEVICE std::size_t index(int i, int j, int k) const {
    return (static_cast<std::uint32_t>(k) * static_cast<std::uint32_t>(ny) + static_cast<std::uint32_t>(j)) *
               static_cast<std::uint32_t>(nx) +
           static_cast<std::uint32_t>(i);
  }
  SLS_HOST_DEVICE bool contains(int i, int j, int k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz;
  }
  // U, W and A with the format known when compiled (the *_as<F> accessors): per-voxel code
  // that reads a voxel's neighbours or a sample's corners tests the format once, where the
  // runtime accessors below test it at every read (a branch, and both formats' address
  // arithmetic, at each of a raycast sample's 16 reads: a third of its instructions, ncu).
  template <VoxelFormat F>
  SLS_HOST_DEVICE float u_as(std::size_t index) const {
    if constexpr (F == VoxelFormat::kFloat32) {
      return u32[index];
    } else {
      return half_to_float(u16[index]);
    }
  }
  template <VoxelFormat F>
  SLS_HOST_DEVICE float w_as(std::size_t index) const {
    if constexpr (F == VoxelFormat::kFloat32) {
      return w32[index];
    } else {
      return static_cast<float>(w8[index]);
    }
  }
  template <VoxelFormat F>
  SLS_HOST_DEVICE void set_u_as(std::size_t index, float value) const {
    if constexpr (F == VoxelFormat::kFloat32) {
      u32[index] = value;
    } else {
      u16[index] = float_to_half(value);
    }
  }
  // Weights are whole numbers in both formats (counts of observations, capped).
  template <VoxelFormat F>
  SLS_HOST_DEVICE void set_w_as(std::size_t index, float weight) const {
    if constexpr (F == VoxelFormat::kFloat32) {
      w32[index] = weight;
    } else {
      w8[index] = static_cast<std::uint8_t>(weight);
    }
  }
  // A: the running average where the volume keeps it, else U (which then is A).
  template <VoxelFormat F>
  SLS_HOST_DEVICE float average_as(std::size_t index) const {
    if constexpr (F == VoxelFormat::kFloat32) {
      return a32 != nullptr ? a32[index] : u32[index];
    } else {
      return half_to_float(a16 != nullptr ? a16[index] : u16[index]);
    }
  }
  // Writes A where the volume keeps it (a TSDF volume's A is its U: nothing to do).
  template <VoxelFormat F>
  SLS_HOST_DEVICE void set_average_as(std::size_t index, float value) const {
    if constexpr (F == VoxelFormat::kFloat32) {
      if (a32 != nullptr) a32[index] = value;
    } else {
      if (a16 != nullptr) a16[index] = float_to_half(value);
    }
  }
  SLS_HOST_DEVICE float u(std::size_t index) const {
    return format == VoxelFormat::kFloat32 ? u_as<VoxelFormat::kFloat32>(index) : u_as<VoxelFormat::kCompact>(index);
  }
  SLS_HOST_DEVICE float w(std::size_t index) const {
    return format == VoxelFormat::kFloat32 ? w_as<VoxelFormat::kFloat32>(index) : w_as<VoxelFormat::kCompact>(index);
  }
  SLS_HOST_DEVICE void set_u(std::size_t index, float value) const {
    if (format == VoxelFormat::kFloat32) {
      set_u_as<VoxelFormat::kFloat32>(index, value);
    } else {
      set_u_as<VoxelFormat::kCompact>(index, value);
    }
  }
  SLS_HOST_DEVICE bool keeps_average() const { return a32 != nullptr || a16 != nullptr; }
  // Bytes a voxel takes (U, W and A where kept): what reading or writing one moves.
  SLS_HOST_DEVICE std::size_t bytes_per_voxel() const { return voxel_bytes(format, keeps_average()); }
  SLS_HOST_DEVICE float average(std::size_t index) const {
    return format == VoxelFormat::kFloat32 ? average_as<VoxelFormat::kFloat32>(index)
                                           : average_as<VoxelFormat::kCompact>(index);
  }
  SLS_HOST_DEVICE void set_average(std::size_t index, float value) const {
    if (format == VoxelFormat::kFloat32) {
      set_average_as<VoxelFormat::kFloat32>(index, value);
    } else {
      set_average_as<VoxelFormat::kCompact>(index, value);
    }
  }
  SLS_HOST_DEVICE void set_w(std::size_t index, float weight) const {
    if (format == VoxelFormat::kFloat32) {
      set_w_as<VoxelFormat::kFloat32>(index, weight);
    } else {
      set_w_as<VoxelFormat::kCompact>(index, weight);
    }
  }
  SLS_HOST_DEVICE int bricks_x() const { return (nx + (1 << kBrickShift) - 1) >> kBrickShift; }
  SLS_HOST_DEVICE int bricks_y() const { return (ny + (1 << kBrickShift) - 1) >> kBrickShift; }
  SLS_HOST_DEVICE int bricks_z() const { return (nz + (1 << kBrickShift) - 1) >> kBrickShift; }
  SLS_HOST_DEVICE std::size_t brick_count() const {
    return static_cast<std::size_t>(bricks_x()) * static_cast<std::size_t>(bricks_y()) *
           static_cast<std::size_t>(bricks_z());
  }
  // In 32-bit arithmetic, widened, as index(): fewer bricks than voxels (a raycast step and
  // an integrated voxel near the surface each look one up).
  SLS_HOST_DEVICE std::size_t brick_index(int bi, int bj, int bk) const {
    return (static_cast<std::uint32_t>(bk) * static_cast<std::uint32_t>(bricks_y()) + static_cast<std::uint32_t>(bj)) *
               static_cast<std::uint32_t>(bricks_x()) +
           static_cast<std::uint32_t>(bi);
  }
  // Flags the bricks within one voxel of voxel (i, j, k): trilinear samples near a brick's
  // face read voxels of the next brick. Racing writers all write 1. Code that writes voxels
  // other than through the integrator calls it for every voxel it gives |U| < 1.
  SLS_HOST_DEVICE void mark_surface(int i, int j, int k) const {
    if (surface_bricks == nullptr) return;
    const int i0 = (i > 0 ? i - 1 : 0) >> kBrickShift, i1 = (i + 1 < nx ? i + 1 : nx - 1) >> kBrickShift;
    const int j0 = (j > 0 ? j - 1 : 0) >> kBrickShift, j1 = (j + 1 < ny ? j + 1 : ny - 1) >> kBrickShift;
    const int k0 = (k > 0 ? k - 1 : 0) >> kBrickShift, k1 = (k + 1 < nz ? k + 1 : nz - 1) >> kBrickShift;
    for (int bk = k0; bk <= k1; ++bk)
      for (int bj = j0; bj <= j1; ++bj)
        for (int bi = i0; bi <= i1; ++bi) {
          // Read first: most flags are already set, and a cached read costs far less than
          // millions of threads writing the same few bytes.
          std::uint8_t& flag = surface_bricks[brick_index(bi, bj, bk)];
          if (flag == 0u) flag = 1u;
        }
  }
  // False only where flags exist and say the brick holding voxel (i, j, k) has no surface.
  SLS_HOST_DEVICE bool may_hold_surface(int i, int j, int k) const {
    return surface_bricks == nullptr ||
           surface_bricks[brick_index(i >> kBrickShift, j >> kBrickShift, k >> kBrickShift)] != 0u;
  }
  SLS_HOST_DEVICE Vec3f voxel_centre(int i, int j, int k) const {
    return Vec3f{(static_cast<float>(i) + 0.5f) * voxel_size_m, (static_cast<float>(j) + 0.5f) * voxel_size_m,
                 (static_cast<float>(k) + 0.5f) * voxel_size_m};
  }
};

// Trilinear U at a volume-frame point; false when a corner lies outside the volume or has
// never been observed (W = 0). The surface is where it crosses 0.
template <VoxelFormat F>
SLS_HOST_DEVICE inline bool sample_u_as(const VolumeView& v, Vec3f point_volume, float* value) {
  // One reciprocal (hoisted out of a caller's loop) rather than three divisions a sample: an
  // IEEE division is a dozen instructions on a GPU, and a raycast samples ~10 times a ray.
  const float to_grid = 1.0f / v.voxel_size_m;
  const float gx = point_volume.x * to_grid - 0.5f;
  const float gy = point_volume.y * to_grid - 0.5f;
  const float gz = point_volume.z * to_grid - 0.5f;
  const float fx = std::floor(gx), fy = std::floor(gy), fz = std::floor(gz);
  const int i = static_cast<int>(fx), j = static_cast<int>(fy), k = static_cast<int>(fz);
  if (i < 0 || j < 0 || k < 0 || i + 1 >= v.nx || j + 1 >= v.ny || k + 1 >= v.nz) return false;
  const float tx = gx - fx, ty = gy - fy, tz = gz - fz;
  // The corners from one index and the strides: the same voxels as index() for each, without
  // eight 64-bit multiplications (integer work was the raycast's busiest pipe, ncu).
  const std::size_t row = static_cast<std::size_t>(v.nx);
  const std::size_t slice = row * static_cast<std::size_t>(v.ny);
  const std::size_t base = v.index(i, j, k);
  const std::size_t offsets[8] = {0, 1, row, row + 1, slice, slice + 1, slice + row, slice + row + 1};
  // All 16 reads first, the test after (the corners lie inside the volume): a GPU thread has
  // them in flight together instead of waiting for each weight before the next read.
  float corner[8];
  bool observed = true;
  for (int c = 0; c < 8; ++c) {
    const std::size_t index = base + offsets[c];
    observed = observed & (v.w_as<F>(index) > 0.0f);  // &, not &&: no branch between the reads
    corner[c] = v.u_as<F>(index);
  }
  if (!observed) return false;
  const float x00 = corner[0] + tx * (corner[1] - corner[0]);
  const float x10 = corner[2] + tx * (corner[3] - corner[2]);
  const float x01 = corner[4] + tx * (corner[5] - corner[4]);
  const float x11 = corner[6] + tx * (corner[7] - corner[6]);
  const float y0 = x00 + ty * (x10 - x00);
  const float y1 = x01 + ty * (x11 - x01);
  *value = y0 + tz * (y1 - y0);
  return true;
}

SLS_HOST_DEVICE inline bool sample_u(const VolumeView& v, Vec3f point_volume, float* value) {
  return v.format == VoxelFormat::kFloat32 ? sample_u_as<VoxelFormat::kFloat32>(v, point_volume, value)
                                           : sample_u_as<VoxelFormat::kCompact>(v, point_volume, value);
}

// Unit gradient of U (the outward surface normal) by central differences of the trilinear
// field, half a voxel either side; false where a sample is missing or the gradient vanishes.
template <VoxelFormat F>
SLS_HOST_DEVICE inline bool surface_normal_as(const VolumeView& v, Vec3f point_volume, Vec3f* normal_volume) {
  const float h = 0.5f * v.voxel_size_m;
  float g[3];
  for (int axis = 0; axis < 3; ++axis) {
    Vec3f plus = point_volume, minus = point_volume;
    if (axis == 0) { plus.x += h; minus.x -= h; }
    if (axis == 1) { plus.y += h; minus.y -= h; }
    if (axis == 2) { plus.z += h; minus.z -= h; }
    float up = 0.0f, down = 0.0f;
    if (!sample_u_as<F>(v, plus, &up) || !sample_u_as<F>(v, minus, &down)) return false;
    g[axis] = up - down;
  }
  const float length = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
  if (!(length > 0.0f)) return false;
  *normal_volume = Vec3f{g[0] / length, g[1] / length, g[2] / length};
  return true;
}

SLS_HOST_DEVICE inline bool surface_normal(const VolumeView& v, Vec3f point_volume, Vec3f* normal_volume) {
  return v.format == VoxelFormat::kFloat32 ? surface_normal_as<VoxelFormat::kFloat32>(v, point_volume, normal_volume)
                                           : surface_normal_as<VoxelFormat::kCompact>(v, point_volume, normal_volume);
}

}  // namespace sls::fusion
