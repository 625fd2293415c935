// Which pixels the stack check (stack_check.h) reads, shared by the CPU gather and the CUDA one
// (cuda/stack_check.cu), so that both hand the check the same samples: `rows` evenly spaced
// rows (the centres of `rows` equal bands), every `stride`-th pixel of each. Rows, not a
// scattered grid: each image is then read in runs of contiguous memory (a grid over 22 images of
// 12 MP was one cache miss per sample, 74 ms a frame); 64 of them, so that an object covering a
// tenth of the view still has six rows across it. Plain structs only: nvcc compiles this.
#pragma once

#include <cstddef>

#include "sdk/core/math_shared.h"

namespace sls {

struct StackCheckGrid {
  int width = 0;     // of the images
  int height = 0;
  int rows = 0;      // sampled rows
  int columns = 0;   // samples per row
  int stride = 1;    // pixels between a row's samples
  SLS_HOST_DEVICE std::size_t count() const {
    return static_cast<std::size_t>(rows) * static_cast<std::size_t>(columns);
  }
  // The image pixel of sample n (row-major over rows, then columns).
  SLS_HOST_DEVICE std::size_t pixel(std::size_t n) const {
    const std::size_t r = n / static_cast<std::size_t>(columns);
    const std::size_t c = n % static_cast<std::size_t>(columns);
    const std::size_t y = (2 * r + 1) * static_cast<std::size_t>(height) / (2 * static_cast<std::size_t>(rows));
    return y * static_cast<std::size_t>(width) + c * static_cast<std::size_t>(stride);
  }
};

// At most `max_samples` pixels (and at least one per row) of a width x height image.
inline StackCheckGrid make_stack_check_grid(int width, int height, std::size_t max_samples) {
  StackCheckGrid grid;
  grid.width = width;
  grid.height = height;
  if (width <= 0 || height <= 0) return grid;
  const auto w = static_cast<std::size_t>(width);
  grid.rows = height < 64 ? height : 64;
  const std::size_t per_row = max_samples / static_cast<std::size_t>(grid.rows) > 0
                                  ? max_samples / static_cast<std::size_t>(grid.rows)
                                  : 1;
  const std::size_t stride = (w + per_row - 1) / per_row;
  grid.stride = static_cast<int>(stride > 0 ? stride : 1);
  grid.columns = static_cast<int>((w + static_cast<std::size_t>(grid.stride) - 1) / static_cast<std::size_t>(grid.stride));
  return grid;
}

}  // namespace sls
