#!/usr/bin/env python3
"""Makes the simulator pictures in docs/ from a recording written by `sls sim`:
a fringe image, the white reference, the ground-truth depth map and valid mask.

    /usr/bin/python3 docs/figures/make_sim_figures.py RECORDING FRAME PREFIX

Uses numpy and open3d (Debian's python3-numpy, python3-open3d) for PNG I/O."""
import json
import sys

import numpy as np
import open3d as o3d


def read_pfm(path):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"Pf"
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4").reshape(height, width)
    return np.flipud(data)


def write_png(path, array8):
    o3d.io.write_image(path, o3d.geometry.Image(np.ascontiguousarray(array8.astype(np.uint8))))


def main():
    recording, frame, prefix = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    manifest = json.load(open(f"{recording}/manifest.json"))
    images = manifest["frames"][frame]["images"]
    labels = [p.get("label", "") for p in manifest["pattern_set"].get("patterns", [])]
    max_dn = (1 << manifest["camera"]["bit_depth"]) - 1
    for index in (0, len(images) - 8, len(images) - 10):
        image = np.asarray(o3d.io.read_image(f"{recording}/{images[index]}")).astype(np.float64)
        write_png(f"{prefix}_pattern{index:02d}.png", np.clip(image / max_dn * 255.0, 0, 255))
    depth = read_pfm(f"{recording}/groundtruth/frames/{frame:06d}/depth.pfm")
    valid = depth > 0
    shown = np.zeros(depth.shape)
    lo, hi = np.percentile(depth[valid], [1, 99])
    shown[valid] = 40 + 215 * np.clip((hi - depth[valid]) / (hi - lo), 0, 1)  # near = bright
    write_png(f"{prefix}_depth.png", shown)
    print(f"depth {lo * 1e3:.3f} .. {hi * 1e3:.3f} mm; labels {labels[:3]}")


if __name__ == "__main__":
    main()
