/* The files a C API scan writes, read back from C99: poses (4x4 row-major doubles) and TUM
 * trajectories, PLY clouds and meshes as sls_scan_write_* writes them. For test_c_scan.c. */
#ifndef SLS_TESTS_API_C_SCAN_FILES_H
#define SLS_TESTS_API_C_SCAN_FILES_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "c_checks.h"

/* ---- Poses: 4x4 row-major doubles. ---- */

static void pose_from_tum(const double t[3], const double q[4] /* x y z w */, double pose[16]) {
  double x = q[0], y = q[1], z = q[2], w = q[3];
  double norm = sqrt(x * x + y * y + z * z + w * w);
  x /= norm, y /= norm, z /= norm, w /= norm;
  pose[0] = 1 - 2 * (y * y + z * z), pose[1] = 2 * (x * y - z * w), pose[2] = 2 * (x * z + y * w), pose[3] = t[0];
  pose[4] = 2 * (x * y + z * w), pose[5] = 1 - 2 * (x * x + z * z), pose[6] = 2 * (y * z - x * w), pose[7] = t[1];
  pose[8] = 2 * (x * z - y * w), pose[9] = 2 * (y * z + x * w), pose[10] = 1 - 2 * (x * x + y * y), pose[11] = t[2];
  pose[12] = 0, pose[13] = 0, pose[14] = 0, pose[15] = 1;
}

/* a^-1 b for rigid poses. */
static void relative_pose(const double a[16], const double b[16], double out[16]) {
  int i, j, k;
  double inverse[16];
  for (i = 0; i < 3; ++i) {
    for (j = 0; j < 3; ++j) inverse[4 * i + j] = a[4 * j + i];
    inverse[4 * i + 3] = -(a[i] * a[3] + a[4 + i] * a[7] + a[8 + i] * a[11]);
  }
  inverse[12] = inverse[13] = inverse[14] = 0, inverse[15] = 1;
  for (i = 0; i < 4; ++i) {
    for (j = 0; j < 4; ++j) {
      out[4 * i + j] = 0;
      for (k = 0; k < 4; ++k) out[4 * i + j] += inverse[4 * i + k] * b[4 * k + j];
    }
  }
}

/* How far apart two poses are: the translation (m) and the rotation angle (degrees). */
static void pose_difference(const double a[16], const double b[16], double* translation_m, double* rotation_deg) {
  double d[16], cosine;
  relative_pose(a, b, d);
  *translation_m = sqrt(d[3] * d[3] + d[7] * d[7] + d[11] * d[11]);
  cosine = 0.5 * (d[0] + d[5] + d[10] - 1.0);
  if (cosine > 1.0) cosine = 1.0;
  if (cosine < -1.0) cosine = -1.0;
  *rotation_deg = acos(cosine) * 180.0 / 3.14159265358979323846;
}

/* A rotation block that is one, and a last row 0 0 0 1. */
static int is_rigid(const double pose[16]) {
  int i, j, k;
  for (i = 0; i < 3; ++i) {
    for (j = 0; j < 3; ++j) {
      double dot = 0;
      for (k = 0; k < 3; ++k) dot += pose[4 * k + i] * pose[4 * k + j];
      if (fabs(dot - (i == j ? 1.0 : 0.0)) > 1e-6) return 0;
    }
  }
  return pose[12] == 0 && pose[13] == 0 && pose[14] == 0 && pose[15] == 1;
}

/* Reads up to `capacity` poses of a TUM trajectory; returns how many, -1 when unreadable. */
static int read_tum(const char* path, double (*poses)[16], int capacity) {
  char line[512];
  int count = 0;
  FILE* file = fopen(path, "r");
  if (file == NULL) return -1;
  while (count < capacity && fgets(line, sizeof(line), file) != NULL) {
    double stamp, t[3], q[4];
    if (line[0] == '#' || line[0] == '\n') continue;
    if (sscanf(line, "%lf %lf %lf %lf %lf %lf %lf %lf", &stamp, &t[0], &t[1], &t[2], &q[0], &q[1], &q[2], &q[3]) != 8) {
      fclose(file);
      return -1;
    }
    pose_from_tum(t, q, poses[count++]);
  }
  fclose(file);
  return count;
}

static int count_tum_poses(const char* path) {
  static double poses[1000][16];
  return read_tum(path, poses, 1000);
}

/* ---- PLY files as sls_scan_write_* writes them (binary little endian). ---- */

typedef struct ply_summary {
  long vertices;
  long faces;
  long vertex_bytes; /* per vertex */
  long header_bytes;
  long file_bytes;
} ply_summary;

static int property_bytes(const char* type) {
  if (strcmp(type, "float") == 0 || strcmp(type, "int") == 0 || strcmp(type, "uint") == 0) return 4;
  if (strcmp(type, "double") == 0) return 8;
  if (strcmp(type, "uchar") == 0 || strcmp(type, "char") == 0) return 1;
  if (strcmp(type, "ushort") == 0 || strcmp(type, "short") == 0) return 2;
  return -1;
}

/* Reads a PLY header; 1 when it is a binary little-endian PLY whose header parses. */
static int read_ply_summary(const char* path, ply_summary* summary) {
  char line[256], type[64], name[64];
  int in_vertex = 0, ok = 0;
  FILE* file = fopen(path, "rb");
  memset(summary, 0, sizeof(*summary));
  if (file == NULL) return 0;
  if (fgets(line, sizeof(line), file) == NULL || strcmp(line, "ply\n") != 0) goto done;
  if (fgets(line, sizeof(line), file) == NULL || strcmp(line, "format binary_little_endian 1.0\n") != 0) goto done;
  while (fgets(line, sizeof(line), file) != NULL) {
    if (strcmp(line, "end_header\n") == 0) {
      ok = 1;
      break;
    }
    if (sscanf(line, "element vertex %ld", &summary->vertices) == 1) {
      in_vertex = 1;
    } else if (sscanf(line, "element face %ld", &summary->faces) == 1) {
      in_vertex = 0;
    } else if (in_vertex && sscanf(line, "property %63s %63s", type, name) == 2) {
      if (property_bytes(type) < 0) goto done;
      summary->vertex_bytes += property_bytes(type);
    }
  }
  summary->header_bytes = ftell(file);
  fseek(file, 0, SEEK_END);
  summary->file_bytes = ftell(file);
done:
  fclose(file);
  return ok;
}

/* A cloud: vertices with positions, exactly as many as the header says, nothing more. */
static void check_cloud_file(const char* path) {
  ply_summary ply;
  CHECK(read_ply_summary(path, &ply));
  CHECK(ply.vertices > 1000);
  CHECK(ply.faces == 0);
  CHECK(ply.vertex_bytes >= 12);
  CHECK(ply.file_bytes == ply.header_bytes + ply.vertices * ply.vertex_bytes);
}

/* A mesh: vertices and triangles (each a count byte and three int indices). */
static void check_mesh_file(const char* path) {
  ply_summary ply;
  CHECK(read_ply_summary(path, &ply));
  CHECK(ply.vertices > 1000 && ply.faces > 1000);
  CHECK(ply.file_bytes == ply.header_bytes + ply.vertices * ply.vertex_bytes + ply.faces * 13);
}

#endif /* SLS_TESTS_API_C_SCAN_FILES_H */
