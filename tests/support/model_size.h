// How much memory a scan's model holds (the soak test and bench_soak): the shipped parts and
// the current volume's surface, cloud and mesh, in MiB.
#pragma once

#include <vector>

#include "fusion/extract.h"
#include "sdk/core/point_cloud.h"
#include "tests/support/process_memory.h"

namespace sls::test {

template <typename T>
double bytes_of(const std::vector<T>& v) {
  return static_cast<double>(v.size() * sizeof(T));
}

inline double cloud_mib(const PointCloud& c) {
  return (bytes_of(c.positions) + bytes_of(c.normals) + bytes_of(c.confidence) + bytes_of(c.colors)) / kMiB;
}

inline double model_mib(const fusion::ExtractedSurface& s) {
  return cloud_mib(s.cloud) + cloud_mib(s.mesh.vertices) + bytes_of(s.mesh.faces) / kMiB;
}

}  // namespace sls::test
