#!/usr/bin/python3
"""Reads a cloud and a mesh PLY written by slscan with Open3D and checks them against the
values the C++ test expects (a JSON file written beside them).

Usage: open3d_read_ply.py CLOUD.ply MESH.ply EXPECTED.json
Exit status: 0 when Open3D reads both files as expected, 1 on any mismatch (each printed),
2 on bad usage, 3 when open3d cannot be imported (it is a declared dependency).

When the checks pass it also writes what it read back, with Open3D's writer, beside
EXPECTED.json (open3d_cloud_ascii.ply in ASCII, open3d_mesh.ply in binary), so the C++ test
can check our reader against a foreign writer.
"""
import json
import math
import os
import sys


def main() -> int:
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        import numpy as np
        import open3d as o3d
    except ImportError as error:  # a declared dependency: fail, never skip
        print(f"cannot import open3d (install Debian's python3-open3d): {error}", file=sys.stderr)
        return 3

    cloud_path, mesh_path, expected_path = sys.argv[1:]
    with open(expected_path, encoding="utf-8") as stream:
        expected = json.load(stream)
    problems = []

    def close(actual, wanted, what, tolerance=1e-6):
        actual = np.asarray(actual, dtype=np.float64)
        wanted = np.asarray(wanted, dtype=np.float64)
        if actual.shape != wanted.shape:
            problems.append(f"{what}: shape {actual.shape}, expected {wanted.shape}")
        elif not np.allclose(actual, wanted, rtol=0.0, atol=tolerance):
            problems.append(f"{what}: {actual.tolist()}, expected {wanted.tolist()}")

    # Point cloud, through the legacy reader MeshLab-style tools resemble.
    cloud = o3d.io.read_point_cloud(cloud_path, format="ply")
    want = expected["cloud"]
    points = np.asarray(cloud.points)
    if len(points) != want["count"]:
        problems.append(f"cloud: {len(points)} points, expected {want['count']}")
    else:
        first = len(want["positions"])
        close(points[:first], want["positions"], "cloud positions", 1e-9)
        if not cloud.has_normals():
            problems.append("cloud: Open3D found no normals")
        else:
            close(np.asarray(cloud.normals)[:first], want["normals"], "cloud normals", 1e-7)
        if not cloud.has_colors():
            problems.append("cloud: Open3D found no colors")
        else:
            # Open3D scales uchar colors to [0, 1].
            close(np.asarray(cloud.colors)[:first] * 255.0, want["colors"], "cloud colors", 1e-6)
        radius = np.linalg.norm(points, axis=1)
        if not np.allclose(radius, want["radius"], atol=1e-6):
            problems.append(f"cloud: radii from {radius.min()} to {radius.max()}, expected {want['radius']}")

    # The tensor reader keeps every vertex property: our confidence and extra properties too.
    tcloud = o3d.t.io.read_point_cloud(cloud_path)
    for name, values in want["properties"].items():
        if name not in tcloud.point:
            problems.append(f"cloud: Open3D's tensor reader found no property '{name}'")
            continue
        close(tcloud.point[name].numpy().reshape(-1)[: len(values)], values, f"cloud property {name}", 1e-7)

    # Triangle mesh.
    mesh = o3d.io.read_triangle_mesh(mesh_path)
    want = expected["mesh"]
    vertices = np.asarray(mesh.vertices)
    triangles = np.asarray(mesh.triangles)
    if len(vertices) != want["vertex_count"]:
        problems.append(f"mesh: {len(vertices)} vertices, expected {want['vertex_count']}")
    if len(triangles) != want["triangle_count"]:
        problems.append(f"mesh: {len(triangles)} triangles, expected {want['triangle_count']}")
    if not problems:
        close(vertices[: len(want["vertices"])], want["vertices"], "mesh vertices", 1e-9)
        close(triangles[: len(want["triangles"])], want["triangles"], "mesh triangles", 0.0)
        if not mesh.is_edge_manifold() or not mesh.is_watertight():
            problems.append("mesh: Open3D does not see a closed manifold surface")
        mesh.compute_triangle_normals()
        # Counter-clockwise seen from outside: every face normal points away from the centre.
        centres = vertices[triangles].mean(axis=1)
        outward = np.einsum("ij,ij->i", np.asarray(mesh.triangle_normals), centres)
        if not np.all(outward > 0):
            problems.append(f"mesh: {int(np.sum(outward <= 0))} faces point inwards")
        area = mesh.get_surface_area()
        if not math.isclose(area, want["area"], rel_tol=1e-5):
            problems.append(f"mesh: surface area {area}, expected {want['area']}")

    for problem in problems:
        print(problem, file=sys.stderr)
    if not problems:
        print(f"open3d {o3d.__version__} read {cloud_path} and {mesh_path} as expected")
        folder = os.path.dirname(os.path.abspath(expected_path))
        written = [
            o3d.io.write_point_cloud(os.path.join(folder, "open3d_cloud_ascii.ply"), cloud, write_ascii=True),
            o3d.io.write_triangle_mesh(os.path.join(folder, "open3d_mesh.ply"), mesh, write_ascii=False),
        ]
        if not all(written):
            problems.append("Open3D could not write its copies of the files")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
