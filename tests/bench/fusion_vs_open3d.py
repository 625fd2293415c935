#!/usr/bin/python3
"""CPU TSDF integration side by side with Open3D (Debian's python3-open3d), in one run.

Makes a depth-mode recording with the simulator (`sls sim --mode depth`), then integrates
the same depth frames with the same ground-truth poses into a cube of the same voxel count,
voxel size and truncation: Open3D's UniformTSDFVolume (its CPU integrator, OpenMP) and ours
(bench_fusion_cpu: TSDF and GTSDF). Open3D's pinhole model has no lens distortion, so it
reads the frames as if undistorted: only the speed is compared. Prints ms per frame.

    tests/bench/fusion_vs_open3d.py BUILD_DIR [--preset demo] [--frames 12] [--voxels 256] [--voxel-um 30]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np
import open3d as o3d


def camera_matrix(calibration_yml):
    text = open(calibration_yml).read()
    block = re.search(r"camera_matrix:.*?data:\s*\[([^\]]*)\]", text, re.S).group(1)
    values = [float(v) for v in block.replace("\n", " ").split(",")]
    return values[0], values[4], values[2], values[5]


def quaternion_matrix(qx, qy, qz, qw):
    return np.array([
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
        [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
        [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]])


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("build", help="build folder holding samples/sls/sls and tests/bench/bench_fusion_cpu")
    parser.add_argument("--preset", default="demo")
    parser.add_argument("--frames", type=int, default=12, help="frames per revolution of the recording (all fused)")
    parser.add_argument("--voxels", type=int, default=256, help="voxels per axis of the cube")
    parser.add_argument("--voxel-um", type=float, default=30.0)
    parser.add_argument("--truncation-voxels", type=float, default=4.0)
    args = parser.parse_args()
    sls = os.path.join(args.build, "samples/sls/sls")
    bench = os.path.join(args.build, "tests/bench/bench_fusion_cpu")
    voxel_m = args.voxel_um * 1e-6
    truncation_m = args.truncation_voxels * voxel_m
    with tempfile.TemporaryDirectory() as tmp:
        rec = os.path.join(tmp, "rec")
        subprocess.run([sls, "sim", "--preset", args.preset, "--frames", str(args.frames), "--mode", "depth",
                        "--device", "cpu", "--out", rec], check=True, stdout=subprocess.DEVNULL)
        manifest = json.load(open(os.path.join(rec, "manifest.json")))
        width, height = manifest["camera"]["width"], manifest["camera"]["height"]
        unit, offset = manifest["depth_encoding"]["unit_m"], manifest["depth_encoding"]["offset_m"]
        fx, fy, cx, cy = camera_matrix(os.path.join(rec, "calibration.yml"))
        poses = []
        for line in open(os.path.join(rec, "groundtruth/trajectory.txt")):
            if line.strip() and not line.startswith("#"):
                t, x, y, z, qx, qy, qz, qw = map(float, line.split())
                pose = np.eye(4)
                pose[:3, :3] = quaternion_matrix(qx, qy, qz, qw)
                pose[:3, 3] = [x, y, z]
                poses.append(pose)  # T_object_camera
        depth_maps = []
        for frame in manifest["frames"]:
            raw = np.asarray(o3d.io.read_image(os.path.join(rec, frame["depth"]))).astype(np.float64)
            depth_maps.append(np.where(raw > 0, offset + unit * raw, 0.0).astype(np.float32))
        # The cube around the first frame's surface (its mean point in the object frame).
        v, u = np.nonzero(depth_maps[0] > 0)
        z = depth_maps[0][v, u]
        points = np.stack([(u - cx) / fx * z, (v - cy) / fy * z, z, np.ones_like(z)])
        centre = (poses[0] @ points)[:3].mean(axis=1)
        length = args.voxels * voxel_m
        origin = centre - 0.5 * length

        intrinsic = o3d.camera.PinholeCameraIntrinsic(width, height, fx, fy, cx, cy)
        black = o3d.geometry.Image(np.zeros((height, width, 3), dtype=np.uint8))
        images = [o3d.geometry.RGBDImage.create_from_color_and_depth(
            black, o3d.geometry.Image(d), depth_scale=1.0, depth_trunc=10.0, convert_rgb_to_intensity=False)
            for d in depth_maps]
        volume = o3d.pipelines.integration.UniformTSDFVolume(
            length=length, resolution=args.voxels, sdf_trunc=truncation_m,
            color_type=o3d.pipelines.integration.TSDFVolumeColorType.NoColor, origin=origin.reshape(3, 1))
        for rgbd, pose in zip(images[:2], poses[:2]):  # warm-up
            volume.integrate(rgbd, intrinsic, np.linalg.inv(pose))
        repeats = 3
        best = float("inf")
        for _ in range(repeats):
            volume.reset()
            start = time.perf_counter()
            for rgbd, pose in zip(images, poses):
                volume.integrate(rgbd, intrinsic, np.linalg.inv(pose))
            best = min(best, (time.perf_counter() - start) / len(images))
        open3d_ms = 1e3 * best
        points = len(volume.extract_point_cloud().points)

        env = dict(os.environ, SLS_BENCH_RECORDING=rec, SLS_BENCH_VOXELS=str(args.voxels), SLS_BENCH_VOXEL_M=repr(voxel_m),
                   SLS_BENCH_ORIGIN=",".join(repr(float(c)) for c in origin), SLS_BENCH_TRUNCATION_M=repr(truncation_m))
        out = subprocess.run([bench, "--benchmark_format=json"], env=env, check=True, capture_output=True, text=True)
        ours = {b["name"].split("/")[1]: b["ms_per_frame"] for b in json.loads(out.stdout)["benchmarks"]}
    print(f"{args.frames} depth frames of {width}x{height} ({args.preset} preset), cube of {args.voxels}^3 voxels of "
          f"{args.voxel_um:g} um, truncation {truncation_m * 1e6:g} um, {os.cpu_count()} cores")
    print(f"  Open3D {o3d.__version__} UniformTSDFVolume (CPU): {open3d_ms:8.2f} ms/frame  ({points} surface points)")
    for name, ms in ours.items():
        print(f"  slscan {name:5s} (CPU):                          {ms:8.2f} ms/frame")
    return 0


if __name__ == "__main__":
    sys.exit(main())
