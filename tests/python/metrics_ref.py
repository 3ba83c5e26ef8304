#!/usr/bin/env python3
"""The reference PSNR and SSIM of image pairs, as scikit-image computes them.

    metrics_ref.py A1.npy B1.npy [A2.npy B2.npy ...]

Each file is an image as .npy: (H, W) grayscale or (H, W, C) interleaved channels, any float
dtype, values nominally in [0, 1]. Both images of a pair are widened to float64 (skimage would
otherwise compute float32 inputs in float32) and scored with

    peak_signal_noise_ratio(a, b, data_range=1)
    structural_similarity(a, b, data_range=1, channel_axis=-1)   # channel_axis=None for (H, W)

Prints one JSON line: a list with one {"psnr": ..., "ssim": ...} per pair, in order; an infinite
PSNR (identical images) is the string "inf", as JSON has no infinity.
"""
import json
import math
import sys

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity


def score(path_a, path_b):
    a = np.load(path_a).astype(np.float64)
    b = np.load(path_b).astype(np.float64)
    if a.ndim not in (2, 3):
        sys.exit(f"metrics_ref: {path_a}: shape {a.shape}, expected (H, W) or (H, W, C)")
    with np.errstate(divide="ignore"):
        psnr = float(peak_signal_noise_ratio(a, b, data_range=1))
    ssim = float(structural_similarity(a, b, data_range=1, channel_axis=-1 if a.ndim == 3 else None))
    return {"psnr": "inf" if math.isinf(psnr) else psnr, "ssim": ssim}


def main(paths):
    if not paths or len(paths) % 2:
        sys.exit("usage: metrics_ref.py A1.npy B1.npy [A2.npy B2.npy ...]")
    print(json.dumps([score(a, b) for a, b in zip(paths[::2], paths[1::2])]))


if __name__ == "__main__":
    main(sys.argv[1:])
