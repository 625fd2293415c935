#!/usr/bin/env python3
"""The same simulated scan on the build machine (x86-64) and on the target (aarch64 under
qemu-user) gives the same model (issue 22). The build machine's `sls` simulates a ci-preset
revolution of the knurled screw in 12 frames (30 deg apart: short enough for the emulator); both
`sls` tools scan that recording on the CPU, decoded and tracked with the turntable prior (without
it, steps this large are lost, and a comparison of one fused frame would say little); the two
results are compared: every pose, the frames fused, the loop closure, and the clouds point by
point. Float rounding may differ (aarch64 contracts a*b+c into one fused multiply-add where
x86-64 without FMA rounds twice), so the models agree within a tolerance, not bit for bit:
poses within 1 um and 0.001 deg, and at least 99 % of each cloud's points within a tenth of a
voxel of the other's (each a tiny fraction of the 30 um camera pixel on the object).

Usage: same_model.py --host-sls PATH --target-sls PATH --work DIR [-- EMULATOR ARGS...] (stdlib only)
"""
import argparse
import json
import math
import pathlib
import shutil
import struct
import subprocess
import sys

FRAMES = 12


def run(command, timeout):
    print("$", " ".join(command), flush=True)
    result = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    if result.returncode != 0:
        sys.exit(f"failed ({result.returncode}): {' '.join(command)}\n{result.stdout}\n{result.stderr}")


def read_cloud(path):
    """The x, y, z of a binary little-endian PLY of float properties (what sls scan writes)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    properties = [line.split()[2] for line in header if line.startswith("property float")]
    if len(properties) != sum(line.startswith("property") for line in header):
        sys.exit(f"{path}: a property that is not float")
    stride = 4 * len(properties)
    xyz = [properties.index(name) for name in ("x", "y", "z")]
    points = []
    for i in range(count):
        values = struct.unpack_from(f"<{len(properties)}f", data, end + i * stride)
        points.append(tuple(values[k] for k in xyz))
    return points


def read_poses(path):
    """TUM trajectory: {timestamp: (t, q)}."""
    poses = {}
    for line in path.read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        v = [float(x) for x in line.split()]
        poses[v[0]] = (v[1:4], v[4:8])
    return poses


def fraction_within(points, others, radius):
    """The fraction of `points` with a point of `others` within `radius` (a hash grid of cells
    of that size: the 27 cells around a point hold every neighbour that close)."""
    grid = {}
    for p in others:
        grid.setdefault(tuple(math.floor(c / radius) for c in p), []).append(p)
    r2 = radius * radius
    near = 0
    for p in points:
        cell = [math.floor(c / radius) for c in p]
        found = False
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    for q in grid.get((cell[0] + dx, cell[1] + dy, cell[2] + dz), ()):
                        if (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2 <= r2:
                            found = True
                            break
                    if found:
                        break
                if found:
                    break
        near += found
    return near / max(len(points), 1)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--host-sls", required=True)
    parser.add_argument("--target-sls", required=True)
    parser.add_argument("--work", required=True)
    argv = sys.argv[1:]
    emulator = argv[argv.index("--") + 1:] if "--" in argv else []
    args = parser.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    work = pathlib.Path(args.work)
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    recording = work / "recording"
    run([args.host_sls, "sim", "--preset", "ci", "--frames", str(FRAMES), "--out", str(recording)], 300)
    host, target = work / "x86-64", work / "aarch64"
    scan = ["scan", "--device", "cpu", "--turntable-prior", "--input", str(recording)]
    run([args.host_sls, *scan, "--out", str(host)], 300)
    run([*emulator, args.target_sls, *scan, "--out", str(target)], 1500)

    reports = [json.loads((d / "report.json").read_text()) for d in (host, target)]
    if reports[0]["frames_fused"] < FRAMES // 2:
        sys.exit(f"the build machine's scan fused only {reports[0]['frames_fused']} of {FRAMES} frames: "
                 "too few to compare tracking on the two machines")
    failures = []
    for key in ("frames_fused", "lost_frames"):
        if reports[0][key] != reports[1][key]:
            failures.append(f"{key}: {reports[0][key]} on x86-64, {reports[1][key]} on aarch64")
    closed = [bool(r.get("loop_closure") and r["loop_closure"].get("closed")) for r in reports]
    if closed[0] != closed[1]:
        failures.append(f"loop closure closed: {closed[0]} on x86-64, {closed[1]} on aarch64")

    poses = [read_poses(d / "trajectory.txt") for d in (host, target)]
    if sorted(poses[0]) != sorted(poses[1]):
        failures.append(f"trajectories of different frames: {sorted(poses[0])} and {sorted(poses[1])}")
    worst_m = worst_deg = 0.0
    for stamp in set(poses[0]) & set(poses[1]):
        (t0, q0), (t1, q1) = poses[0][stamp], poses[1][stamp]
        worst_m = max(worst_m, math.dist(t0, t1))
        dot = min(1.0, abs(sum(a * b for a, b in zip(q0, q1))))
        worst_deg = max(worst_deg, math.degrees(2.0 * math.acos(dot)))
    print(f"poses of {len(poses[0])} frames: worst {worst_m * 1e6:.4f} um, {worst_deg:.6f} deg apart")
    if worst_m > 1e-6 or worst_deg > 1e-3:
        failures.append(f"poses differ by up to {worst_m * 1e6:.3f} um / {worst_deg:.5f} deg (1 um / 0.001 deg allowed)")

    clouds = [read_cloud(d / "cloud.ply") for d in (host, target)]
    voxel_m = reports[0]["voxel_size_m"]
    radius = 0.1 * voxel_m
    near = [fraction_within(clouds[0], clouds[1], radius), fraction_within(clouds[1], clouds[0], radius)]
    print(f"clouds: {len(clouds[0])} points on x86-64, {len(clouds[1])} on aarch64; within {radius * 1e6:.2f} um "
          f"of the other's: {near[0] * 100:.3f} % and {near[1] * 100:.3f} %")
    if min(near) < 0.99:
        failures.append(f"only {min(near) * 100:.2f} % of a cloud's points within a tenth of a voxel of the other's "
                        "(99 % needed)")
    if failures:
        sys.exit("the aarch64 model differs from the x86-64 one:\n  " + "\n  ".join(failures))
    print("same model on x86-64 and aarch64")


if __name__ == "__main__":
    main()
