#!/usr/bin/env python3
"""Export the LPIPS (net='alex', version='0.1') weights to evblur's weights file.

    pip install torch torchvision lpips
    python benchmark/scripts/export_lpips_weights.py lpips_alex_v0.1.bin [--check DIR]

Builds `lpips.LPIPS(net='alex', version='0.1')` (the linear heads ship with the `lpips` package;
torchvision downloads the ImageNet AlexNet backbone on first use) and writes the five `features`
convolutions (weight, bias) and the five heads in the format of `lpips_format.py`. Point
evblur at the file with `EVBLUR_LPIPS_WEIGHTS=lpips_alex_v0.1.bin` (or the benchmark's flag).

With `--check DIR` it also saves a deterministic image pair as DIR/a.npy, DIR/b.npy ((H, W, 3)
float32 in [0, 1]) and prints the package's own distance of that pair, to compare with

    python tests/python/lpips_ref.py lpips_alex_v0.1.bin DIR/a.npy DIR/b.npy
"""
import argparse
import os
import sys

import numpy as np
import torch
import lpips

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lpips_format  # noqa: E402


def tensors(model):
    """The file's tensors (name -> float32 array) from an lpips.LPIPS alex model."""
    convs = [m for m in model.net.modules() if isinstance(m, torch.nn.Conv2d)]
    if len(convs) != 5:
        sys.exit(f"export_lpips_weights: {len(convs)} convolutions in the backbone, expected AlexNet's 5")
    out = {}
    for i, conv in enumerate(convs, start=1):
        out[f"conv{i}.weight"] = conv.weight.detach().cpu().numpy()
        out[f"conv{i}.bias"] = conv.bias.detach().cpu().numpy()
    for l, lin in enumerate(model.lins):
        # NetLinLayer: [Dropout,] Conv2d(C, 1, 1, bias=False); weight (1, C, 1, 1) -> (C,).
        out[f"lin{l}.weight"] = lin.model[-1].weight.detach().cpu().numpy().reshape(-1)
    return out


def check_pair(model, folder):
    """Save a deterministic 64x96 image pair to `folder` and return the package's distance."""
    h, w = 64, 96
    y, x = np.mgrid[0:h, 0:w] / np.array([h, w])[:, None, None]
    base = np.stack([0.2 + 0.6 * x, 0.3 + 0.4 * y, 0.5 + 0.3 * np.sin(9 * x + 4 * y)], axis=-1)
    noise = np.random.default_rng(0).uniform(-0.1, 0.1, base.shape)
    a, b = base.astype(np.float32), np.clip(base + noise, 0, 1).astype(np.float32)
    os.makedirs(folder, exist_ok=True)
    np.save(os.path.join(folder, "a.npy"), a)
    np.save(os.path.join(folder, "b.npy"), b)
    to_torch = lambda im: torch.from_numpy(im).permute(2, 0, 1)[None]  # noqa: E731
    with torch.no_grad():
        return float(model(to_torch(a), to_torch(b), normalize=True))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="the weights file to write")
    parser.add_argument("--check", metavar="DIR", help="also save a test pair here and print its distance")
    args = parser.parse_args()
    model = lpips.LPIPS(net="alex", version="0.1", verbose=False).eval()
    lpips_format.write(args.out, tensors(model))
    print(f"wrote {args.out}")
    if args.check:
        print(f"lpips package distance of {args.check}/a.npy, b.npy: {check_pair(model, args.check):.8f}")


if __name__ == "__main__":
    main()
