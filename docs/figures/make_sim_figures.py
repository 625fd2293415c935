#!/usr/bin/env python3
"""Makes the simulator pictures in docs/ from a recording written by `sls sim`: for a few
pattern images and the ground-truth depth map, the whole frame shrunk to 1000 px wide and a
1:1 crop of its centre.

    /usr/bin/python3 docs/figures/make_sim_figures.py RECORDING FRAME OUT_PREFIX

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
    o3d.io.write_image(path, o3d.geometry.Image(np.ascontiguousarray(np.clip(array8, 0, 255).astype(np.uint8))))


def shrink(image, width=1000):
    factor = max(1, image.shape[1] // width)
    h, w = image.shape[0] // factor * factor, image.shape[1] // factor * factor
    return image[:h, :w].reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))


def centre_crop(image, width=800, height=600):
    y0, x0 = (image.shape[0] - height) // 2, (image.shape[1] - width) // 2
    return image[y0:y0 + height, x0:x0 + width]


def save_both(prefix, name, image8):
    write_png(f"{prefix}_{name}.png", shrink(image8))
    write_png(f"{prefix}_{name}_crop.png", centre_crop(image8))


def main():
    recording, frame, prefix = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    manifest = json.load(open(f"{recording}/manifest.json"))
    images = manifest["frames"][frame]["images"]
    max_dn = (1 << manifest["camera"]["bit_depth"]) - 1
    names = {0: "white", len(images) - 12: "gray_bit4", len(images) - 8: "phase0"}
    for index, name in names.items():
        image = np.asarray(o3d.io.read_image(f"{recording}/{images[index]}")).astype(np.float64)
        save_both(prefix, name, image / max_dn * 255.0)
    depth = read_pfm(f"{recording}/groundtruth/frames/{frame:06d}/depth.pfm").astype(np.float64)
    valid = depth > 0
    lo, hi = np.percentile(depth[valid], [0.5, 99.5])
    shown = np.zeros(depth.shape)
    shown[valid] = 40 + 215 * np.clip((hi - depth[valid]) / (hi - lo), 0, 1)  # near = bright
    save_both(prefix, "depth", shown)
    print(f"depth {lo * 1e3:.3f} .. {hi * 1e3:.3f} mm")


if __name__ == "__main__":
    main()
