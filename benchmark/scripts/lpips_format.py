"""The LPIPS weights file of evblur (read by benchmark/src/lpips/weights.rs): the one writer, and
a reader, needing numpy only.

Everything little-endian:

    magic     8 bytes  b"EVBLPIPS"
    version   u32      1
    count     u32      15
    count times:
      name_len  u32    then name_len bytes of UTF-8 name
      rank      u32    then rank u32 dimensions
      data      f32    product(dimensions) values, row-major (C order)

The tensors come in the order of TENSORS, with those names and shapes (PyTorch layouts): the five
AlexNet `features` convolutions (weight (out, in, k, k), bias (out,)), then the five LPIPS linear
heads lin0..lin4 (the (1, C, 1, 1) 1x1-convolution weights flattened to (C,), all >= 0 in v0.1).
"""
import struct

import numpy as np

MAGIC = b"EVBLPIPS"
VERSION = 1

# (name, shape) in file order.
_CONVS = [(64, 3, 11), (192, 64, 5), (384, 192, 3), (256, 384, 3), (256, 256, 3)]
TENSORS = [
    t
    for i, (c_out, c_in, k) in enumerate(_CONVS, start=1)
    for t in ((f"conv{i}.weight", (c_out, c_in, k, k)), (f"conv{i}.bias", (c_out,)))
] + [(f"lin{l}.weight", (c_out,)) for l, (c_out, _, _) in enumerate(_CONVS)]


def write(path, tensors):
    """Write `tensors` (a mapping name -> array-like of exactly the TENSORS names and shapes) to
    `path` as float32. Raises ValueError on a missing, extra or misshapen tensor, a non-finite
    value, or a negative head weight."""
    extra = set(tensors) - {name for name, _ in TENSORS}
    if extra:
        raise ValueError(f"unexpected tensors {sorted(extra)}; expected {[n for n, _ in TENSORS]}")
    out = bytearray(MAGIC + struct.pack("<II", VERSION, len(TENSORS)))
    for name, shape in TENSORS:
        if name not in tensors:
            raise ValueError(f"missing tensor {name} {shape}")
        a = np.asarray(tensors[name], dtype=np.float32)
        if a.shape != shape:
            raise ValueError(f"{name}: shape {a.shape}, expected {shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: non-finite values")
        if name.startswith("lin") and np.any(a < 0):
            raise ValueError(f"{name}: negative head weights (LPIPS v0.1 heads are >= 0)")
        encoded = name.encode("utf-8")
        out += struct.pack("<I", len(encoded)) + encoded
        out += struct.pack(f"<I{len(shape)}I", len(shape), *shape)
        out += np.ascontiguousarray(a).astype("<f4").tobytes()
    with open(path, "wb") as f:
        f.write(out)


def read(path):
    """The tensors of the file at `path`, name -> float32 array, checked against TENSORS."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != MAGIC:
        raise ValueError(f"{path}: not an LPIPS weights file")
    version, count = struct.unpack_from("<II", data, 8)
    if version != VERSION or count != len(TENSORS):
        raise ValueError(f"{path}: version {version}, {count} tensors; expected {VERSION}, {len(TENSORS)}")
    pos, tensors = 16, {}
    for name, shape in TENSORS:
        (n,) = struct.unpack_from("<I", data, pos)
        found = data[pos + 4 : pos + 4 + n].decode("utf-8")
        pos += 4 + n
        (rank,) = struct.unpack_from("<I", data, pos)
        dims = struct.unpack_from(f"<{rank}I", data, pos + 4)
        pos += 4 + 4 * rank
        if found != name or dims != shape:
            raise ValueError(f"{path}: tensor {found} {dims}, expected {name} {shape}")
        size = int(np.prod(shape))
        if pos + 4 * size > len(data):
            raise ValueError(f"{path}: truncated in {name}")
        tensors[name] = np.frombuffer(data, "<f4", size, pos).reshape(shape)
        pos += 4 * size
    if pos != len(data):
        raise ValueError(f"{path}: {len(data) - pos} bytes after the last tensor")
    return tensors
