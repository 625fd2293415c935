// PLY files for point clouds and triangle meshes (design brief, section 5).
//
// Writing: always binary_little_endian 1.0 with the property names MeshLab, CloudCompare and
// Open3D expect:
//   element vertex N
//     property float x, y, z                 metres
//     property float nx, ny, nz              if the cloud has normals
//     property float confidence              if the cloud has confidence
//     property uchar red, green, blue        if the cloud has colors
//     property float <name>                  one per PointProperty, in order
//   element face F                           meshes only
//     property list uchar int vertex_indices
// The file is written atomically (temporary file + rename), so a crash never leaves half a file.
//
// Reading: ascii, binary_little_endian and binary_big_endian; every scalar type (char/int8,
// uchar/uint8, short/int16, ushort/uint16, int/int32, uint/uint32, float/float32,
// double/float64). Elements other than "vertex" and "face" are skipped, as are list
// properties of the vertex element and other properties of the face element. Vertex
// properties map as follows: x y z -> positions, nx ny nz -> normals (all three or none),
// red green blue -> colors (all three or none; integer types clamped to [0, 255], floating
// types taken as [0, 1] and scaled), confidence -> confidence; every other scalar becomes a
// PointProperty of that name, converted to float. Faces come from the list "vertex_indices"
// (or "vertex_index") with any integer count and index types; polygons with more than three
// vertices are triangulated as a fan, faces with fewer than three are dropped.
//
// A position (x, y, z) that is NaN or infinite (also a double too large for float) makes the
// file invalid; other properties, normals included, are taken as they are.
//
// Errors: sls::Error whose message names the file: kNotFound / kIo when the file cannot be
// opened or read or is not a regular file (a FIFO, a device, a directory: refused without
// reading), kFormat for corrupt or unsupported content (bad magic, truncated header or data,
// counts the file cannot hold, face indices out of range, missing x/y/z, a non-finite
// position, a file over 64 GiB), kInvalidArgument for an inconsistent cloud or mesh given to
// a writer.
#pragma once

#include <string>
#include <string_view>

#include "sdk/core/point_cloud.h"

namespace sls {

void write_ply(const std::string& path, const PointCloud& cloud);
void write_ply(const std::string& path, const TriangleMesh& mesh);

// Reads the vertices of any PLY file (faces, if present, are skipped).
PointCloud read_ply_cloud(const std::string& path);
// Reads vertices and faces; a file with no face element gives a mesh with no faces.
TriangleMesh read_ply_mesh(const std::string& path);

// The same in memory: the exact bytes write_ply writes, and parsers of a file's bytes where
// `source` names the data in error messages (usually its path).
std::string encode_ply(const PointCloud& cloud);
std::string encode_ply(const TriangleMesh& mesh);
PointCloud decode_ply_cloud(std::string_view bytes, const std::string& source);
TriangleMesh decode_ply_mesh(std::string_view bytes, const std::string& source);

}  // namespace sls
