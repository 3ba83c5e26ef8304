#!/usr/bin/env python3
"""Open an Ev-DeblurBlender dataset folder the way the reference Ev-DeblurNeRF loader does
(numpy + h5py only) and assert what it relies on; exit non-zero with a message on failure.

    read_dataset.py DIR [--events-unit ns|us] [--test-views every8|last5]

Checked (see dataset-format.md): images_1/*.png headers (8-bit RGB/RGBA, one size, sorted
names); images_1/timestamps.npz (float64 (N,), timestamps_start > 0 as the loader asserts,
start <= mid <= end, sharp views start == end at the held-out indices); poses_bounds.npy and
all_poses_bounds.npy (float64 (., 17), the loader's [c1, -c0, c2] column swap gives a pure
rotation, hwf = image size, 0 < near < far); all_timestamps.npy strictly increasing and covering
every exposure; events.h5 x, y, t, p 1-D of equal length, t sorted and inside the dense
trajectory (the loader would drop the others), p in {0, 1} or {-1, +1}, 0 <= x < W, 0 <= y < H.
"""
import argparse
import os
import struct
import sys

import h5py
import numpy as np


def fail(msg):
    print(f"read_dataset: {msg}", file=sys.stderr)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def png_header(path):
    """(width, height, bit depth, colour type) from the IHDR chunk."""
    with open(path, "rb") as f:
        b = f.read(33)
    check(b[:8] == b"\x89PNG\r\n\x1a\n" and b[12:16] == b"IHDR", f"{path}: not a PNG")
    w, h = struct.unpack(">II", b[16:24])
    return w, h, b[24], b[25]


def load_llff(path, n, hw):
    """The LLFF loader's reading of poses_bounds.npy: returns (poses 3x5xN after the column swap, bounds 2xN)."""
    arr = np.load(path)
    check(arr.dtype == np.float64, f"{path}: dtype {arr.dtype}, expected float64")
    check(arr.ndim == 2 and arr.shape[1] == 17, f"{path}: shape {arr.shape}, expected (N, 17)")
    if n is not None:
        check(arr.shape[0] == n, f"{path}: {arr.shape[0]} rows for {n} images")
    poses = arr[:, :-2].reshape([-1, 3, 5]).transpose([1, 2, 0])
    bds = arr[:, -2:].transpose([1, 0])
    h, w = hw
    check(np.allclose(poses[0, 4, :], h) and np.allclose(poses[1, 4, :], w),
          f"{path}: hwf height/width {poses[0, 4, 0]}/{poses[1, 4, 0]} != image {h}/{w}")
    check((poses[2, 4, :] > 0).all(), f"{path}: focal not positive")
    # [down, right, backward] -> [right, up, backward], as the loader does.
    poses = np.concatenate([poses[:, 1:2, :], -poses[:, 0:1, :], poses[:, 2:, :]], 1)
    rot = poses[:, :3, :].transpose([2, 0, 1])
    eye = np.einsum("nji,njk->nik", rot, rot)
    err = np.abs(eye - np.eye(3)).max()
    det = np.linalg.det(rot)
    check(err < 1e-4 and np.abs(det - 1).max() < 1e-4, f"{path}: not a pure rotation (|R^T R - I| {err}, det {det.min()}..{det.max()})")
    check((bds[0] > 0).all() and (bds[1] > bds[0]).all(), f"{path}: need 0 < near < far")
    scale = 1.0 / (bds.min() * 0.75)
    check(np.isfinite(scale), f"{path}: scene scale 1 / (0.75 min(near)) is not finite")
    return poses, bds


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--events-unit", choices=["ns", "us"], default="ns")
    ap.add_argument("--test-views", choices=["every8", "last5"], default="every8")
    a = ap.parse_args()
    d = a.dir

    names = sorted(f for f in os.listdir(os.path.join(d, "images_1")) if f.lower().endswith(".png"))
    n = len(names)
    check(n > 0, "images_1: no PNG images")
    heads = [png_header(os.path.join(d, "images_1", f)) for f in names]
    w, h = heads[0][:2]
    for f, (wi, hi, depth, colour) in zip(names, heads):
        check((wi, hi) == (w, h), f"images_1/{f}: {wi}x{hi}, expected {w}x{h}")
        check(depth == 8 and colour in (2, 6), f"images_1/{f}: bit depth {depth}, colour type {colour}; expected 8-bit RGB")

    z = np.load(os.path.join(d, "images_1", "timestamps.npz"))
    ts = {k: z[k] for k in ("timestamps", "timestamps_start", "timestamps_end")}
    for k, v in ts.items():
        check(v.dtype == np.float64 and v.shape == (n,), f"timestamps.npz: {k} is {v.dtype} {v.shape}, expected float64 ({n},)")
    mid, start, end = ts["timestamps"], ts["timestamps_start"], ts["timestamps_end"]
    check((start > 0).all(), "timestamps.npz: the loader asserts timestamps_start > 0")
    check(((start <= mid) & (mid <= end)).all(), "timestamps.npz: need start <= mid <= end")
    i_test = np.arange(n)[::8] if a.test_views == "every8" else np.arange(n)[-5:]
    sharp = np.flatnonzero(start == end)
    check(np.array_equal(sharp, i_test), f"timestamps.npz: sharp views {sharp.tolist()} != test views {i_test.tolist()}")

    load_llff(os.path.join(d, "poses_bounds.npy"), n, (h, w))
    all_poses, _ = load_llff(os.path.join(d, "all_poses_bounds.npy"), None, (h, w))
    all_t = np.load(os.path.join(d, "all_timestamps.npy"))
    check(all_t.dtype == np.float64 and all_t.shape == (all_poses.shape[2],),
          f"all_timestamps.npy: {all_t.dtype} {all_t.shape}, expected float64 ({all_poses.shape[2]},)")
    check((np.diff(all_t) > 0).all(), "all_timestamps.npy: not strictly increasing")
    lo, hi = all_t.min(), all_t.max()
    check((start >= lo).all() and (end <= hi).all(), "timestamps.npz: an exposure window leaves the dense trajectory")

    with h5py.File(os.path.join(d, "events.h5"), "r") as f:
        x, y, t, p = (f[k][:] for k in ("x", "y", "t", "p"))
    check(x.ndim == y.ndim == t.ndim == p.ndim == 1, "events.h5: x, y, t, p must be 1-D")
    check(len(x) == len(y) == len(t) == len(p), "events.h5: x, y, t, p lengths differ")
    check((np.diff(t) >= 0).all(), "events.h5: t is not sorted")
    t_us = t / 1000.0 if a.events_unit == "ns" else t.astype(np.float64)
    kept = (t_us >= lo) & (t_us <= hi)
    check(kept.all(), f"events.h5: {np.count_nonzero(~kept)} events outside [{lo}, {hi}] us (the loader drops them)")
    pv = set(np.unique(p.astype(np.int64)).tolist())
    check(pv <= {0, 1} or pv <= {-1, 1}, f"events.h5: p values {sorted(pv)}, expected {{0, 1}} or {{-1, +1}}")
    if np.issubdtype(x.dtype, np.integer):
        check(((x >= 0) & (x < w)).all() and ((y >= 0) & (y < h)).all(), "events.h5: x/y outside the image")
    on = int(np.count_nonzero(p > 0))
    print(f"read_dataset: ok: {n} images {w}x{h}, {len(sharp)} sharp, {all_t.size} dense poses, "
          f"{len(t)} events ({on} ON) t {t.min() if len(t) else '-'}..{t.max() if len(t) else '-'} {a.events_unit}")


if __name__ == "__main__":
    main()
