#!/usr/bin/env python3
"""Side-by-side pictures of two fused models (like the paper's Figure 1): the render.png
that `sls scan` writes for each (the model raycast from the first view, raking light), left
and right, with a white gap, plus a 2x enlargement of the centre.

    /usr/bin/python3 docs/figures/make_fusion_figures.py LEFT.png RIGHT.png OUT_PREFIX

Uses numpy and open3d (Debian's python3-numpy, python3-open3d) for PNG I/O."""
import sys

import numpy as np
import open3d as o3d


def read(path):
    image = np.asarray(o3d.io.read_image(path))
    return image if image.ndim == 2 else image[..., 0]


def write(path, image):
    o3d.io.write_image(path, o3d.geometry.Image(np.ascontiguousarray(image.astype(np.uint8))))


def side_by_side(left, right, gap=8):
    return np.concatenate([left, np.full((left.shape[0], gap), 255, np.uint8), right], axis=1)


def centre_zoom(image, factor=2):
    h, w = image.shape[0] // (2 * factor), image.shape[1] // (2 * factor)
    y0, x0 = (image.shape[0] - 2 * h) // 2, (image.shape[1] - 2 * w) // 2
    crop = image[y0:y0 + 2 * h, x0:x0 + 2 * w]
    return np.repeat(np.repeat(crop, factor, axis=0), factor, axis=1)


def main():
    left, right, prefix = read(sys.argv[1]), read(sys.argv[2]), sys.argv[3]
    write(prefix + ".png", side_by_side(left, right))
    write(prefix + "_zoom.png", side_by_side(centre_zoom(left), centre_zoom(right)))


if __name__ == "__main__":
    main()
