#!/usr/bin/env python3
"""Score image pairs with the PyTorch `lpips` package (net='alex', version='0.1') running on
evblur's LPIPS weights, to compare our weights and implementations with the package.

    compare_lpips_torch.py WEIGHTS A1 B1 [A2 B2 ...] [--float64]
    compare_lpips_torch.py WEIGHTS --pairs PAIRS.txt [--float64]

WEIGHTS is an evblur LPIPS weights file (lpips_format.py). Images are PNG files or .npy arrays
(H, W, 3) RGB in [0, 1]; PAIRS.txt has one "name a b" line per pair, paths relative to its folder.
Needs torch, torchvision, lpips, numpy and pillow.

The package's AlexNet trunk is built untrained (pnet_rand=True: no torchvision download) and our
five convolutions are copied into it; its linear heads are its own weights/v0.1/alex.pth. Prints
JSON lines: first the largest |package head - our head| (overall and per layer), then one line per
pair with the package's distance (normalize=True, inputs in [0, 1]) and its per-layer terms, and
the distance with the package's heads replaced by ours ("distance_our_heads").
"""
import argparse
import copy
import json
import os
import sys

import numpy as np
import torch
from PIL import Image

import lpips

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lpips_format  # noqa: E402


def load_image(path):
    """An (H, W, 3) float64 array in [0, 1] from a PNG (or any Pillow image) or an .npy file."""
    if path.endswith(".npy"):
        image = np.load(path).astype(np.float64)
    else:
        with Image.open(path) as im:
            image = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    if image.ndim != 3 or image.shape[2] != 3:
        sys.exit(f"compare_lpips_torch: {path}: shape {image.shape}, expected (H, W, 3)")
    return image


def heads(model):
    """The package model's five head weights, each flattened to (C,)."""
    return [lin.model[-1].weight.detach().reshape(-1) for lin in model.lins]


def build_models(weights, dtype):
    """The package's LPIPS with our trunk, and a copy of it with our heads too."""
    model = lpips.LPIPS(net="alex", version="0.1", pretrained=True, pnet_rand=True, verbose=False)
    convs = [m for m in model.net.modules() if isinstance(m, torch.nn.Conv2d)]
    if len(convs) != 5:
        sys.exit(f"compare_lpips_torch: the package's AlexNet has {len(convs)} convolutions, expected 5")
    with torch.no_grad():
        for i, conv in enumerate(convs, start=1):
            for name, param in (("weight", conv.weight), ("bias", conv.bias)):
                ours = torch.from_numpy(np.array(weights[f"conv{i}.{name}"]))
                if ours.shape != param.shape:
                    sys.exit(f"compare_lpips_torch: conv{i}.{name}: ours {tuple(ours.shape)}, package {tuple(param.shape)}")
                param.copy_(ours)
    ours_model = copy.deepcopy(model)
    with torch.no_grad():
        for l, lin in enumerate(ours_model.lins):
            w = lin.model[-1].weight
            w.copy_(torch.from_numpy(np.array(weights[f"lin{l}.weight"])).reshape(w.shape))
    return model.to(dtype).eval(), ours_model.to(dtype).eval()


def read_pairs(path):
    """(name, a, b) per non-empty line of a pairs file, paths relative to its folder."""
    folder = os.path.dirname(os.path.abspath(path))
    pairs = []
    with open(path) as f:
        for line in f:
            fields = line.split()
            if not fields:
                continue
            if len(fields) != 3:
                sys.exit(f"compare_lpips_torch: {path}: expected 'name a b', got {line.strip()!r}")
            name, a, b = fields
            pairs.append((name, os.path.join(folder, a), os.path.join(folder, b)))
    return pairs


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("weights", help="evblur LPIPS weights file")
    parser.add_argument("images", nargs="*", help="A1 B1 [A2 B2 ...]")
    parser.add_argument("--pairs", help="a file of 'name a b' lines")
    parser.add_argument("--float64", action="store_true", help="run the networks in float64")
    args = parser.parse_args()
    if len(args.images) % 2:
        parser.error("images come in pairs")
    pairs = [(f"{a} {b}", a, b) for a, b in zip(args.images[::2], args.images[1::2])]
    if args.pairs:
        pairs += read_pairs(args.pairs)
    if not pairs:
        parser.error("no image pairs")

    weights = lpips_format.read(args.weights)
    dtype = torch.float64 if args.float64 else torch.float32
    model, ours_model = build_models(weights, dtype)

    diffs = [
        float((package - torch.from_numpy(np.array(weights[f"lin{l}.weight"])).to(dtype)).abs().max())
        for l, package in enumerate(heads(model))
    ]
    print(json.dumps({"heads_max_abs_diff": max(diffs), "per_layer": diffs}))

    with torch.no_grad():
        for name, path_a, path_b in pairs:
            a, b = load_image(path_a), load_image(path_b)
            if a.shape != b.shape:
                sys.exit(f"compare_lpips_torch: {path_a} {a.shape}, {path_b} {b.shape}: sizes differ")
            ta, tb = (torch.from_numpy(x.transpose(2, 0, 1)[None].copy()).to(dtype) for x in (a, b))
            distance, layers = model(ta, tb, retPerLayer=True, normalize=True)
            ours = ours_model(ta, tb, normalize=True)
            print(json.dumps({
                "name": name,
                "shape": list(a.shape),
                "distance": float(distance),
                "layers": [float(x) for x in layers],
                "distance_our_heads": float(ours),
            }), flush=True)


if __name__ == "__main__":
    main()
