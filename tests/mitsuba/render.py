#!/usr/bin/env python3
"""Render an evblur Mitsuba export (scene.json + assets) with Mitsuba 3.

    render.py SCENE_JSON --out OUT.exr [--spp N] [--seed S] [--variant llvm_ad_rgb]

scene.json is written by `simulator::export::export_mitsuba`: {"format": "evblur-mitsuba-1",
"scene": <dict for mi.load_dict>} where {"look_at": {...}} and {"matrix": [...]} stand for
transforms and every "filename" is relative to scene.json. Writes a linear float32 RGB EXR and
prints one JSON line: variant, spp, seed, load_s (parse + scene build), warmup_s (a 1-spp render
that pays for JIT compilation; llvm only), render_s (the measured render) and samples_per_s.
"""
import argparse
import json
import os
import sys
import time


def convert(obj, base, mi):
    """Turn the JSON scene description into a load_dict dict."""
    if isinstance(obj, dict):
        if set(obj) == {"look_at"}:
            la = obj["look_at"]
            return mi.ScalarTransform4f().look_at(origin=la["origin"], target=la["target"], up=la["up"])
        if set(obj) == {"matrix"}:
            return mi.ScalarTransform4f(obj["matrix"])
        out = {}
        for key, value in obj.items():
            if key == "filename":
                out[key] = os.path.join(base, value)
            else:
                out[key] = convert(value, base, mi)
        return out
    if isinstance(obj, list):
        return [convert(v, base, mi) for v in obj]
    return obj


def llvm_ok():
    """True when a system libLLVM >= 19 is installed (Dr.Jit finds it by itself)."""
    import glob
    for path in glob.glob("/usr/lib/*/libLLVM*.so*") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*"):
        digits = "".join(c if c.isdigit() else " " for c in os.path.basename(path)).split()
        if digits and int(digits[0]) >= 19:
            return True
    return False


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene_json")
    ap.add_argument("--out", required=True, help="output EXR (linear float32 RGB)")
    ap.add_argument("--spp", type=int, default=None, help="samples per pixel (default: scene.json)")
    ap.add_argument("--seed", type=int, default=None, help="sampler seed (default: scene.json)")
    ap.add_argument("--variant", default="llvm_ad_rgb", help="Mitsuba variant; falls back to scalar_rgb")
    args = ap.parse_args()

    import mitsuba as mi

    variant = args.variant
    if variant.startswith("llvm") and not os.environ.get("DRJIT_LIBLLVM_PATH") and not llvm_ok():
        # with LLVM < 19 the llvm variants abort the whole process mid-render
        print(f"render.py: no libLLVM >= 19 found; using scalar_rgb instead of {variant}", file=sys.stderr)
        variant = "scalar_rgb"
    try:
        mi.set_variant(variant)
    except Exception as e:  # variant not compiled in, or no usable LLVM
        print(f"render.py: variant {variant} unavailable ({e}); using scalar_rgb", file=sys.stderr)
        variant = "scalar_rgb"
        mi.set_variant(variant)

    t0 = time.perf_counter()
    with open(args.scene_json) as f:
        doc = json.load(f)
    if doc.get("format") != "evblur-mitsuba-1":
        sys.exit(f"{args.scene_json}: format {doc.get('format')!r} is not evblur-mitsuba-1; re-export the scene")
    base = os.path.dirname(os.path.abspath(args.scene_json))
    desc = convert(doc["scene"], base, mi)
    sampler = desc["sensor"]["sampler"]
    if args.spp is not None:
        sampler["sample_count"] = args.spp
    if args.seed is not None:
        sampler["seed"] = args.seed
    spp = sampler["sample_count"]
    seed = sampler["seed"]
    scene = mi.load_dict(desc)
    load_s = time.perf_counter() - t0

    warmup_s = 0.0
    if variant.startswith("llvm") or variant.startswith("cuda"):
        # a 1-spp render with another seed compiles the kernels; the timed render reuses them
        t0 = time.perf_counter()
        img = mi.render(scene, seed=seed + 0x5EED, spp=1)
        mi.Bitmap(img)  # force evaluation
        warmup_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    img = mi.render(scene, seed=seed, spp=spp)
    bitmap = mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB)
    render_s = time.perf_counter() - t0
    bitmap.write(args.out)

    film = scene.sensors()[0].film().crop_size()
    samples = int(film[0]) * int(film[1]) * spp
    print(json.dumps({
        "variant": variant, "spp": spp, "seed": seed, "width": int(film[0]), "height": int(film[1]),
        "load_s": round(load_s, 3), "warmup_s": round(warmup_s, 3), "render_s": round(render_s, 3),
        "samples_per_s": round(samples / max(render_s, 1e-9)),
    }))


if __name__ == "__main__":
    main()
