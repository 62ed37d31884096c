#!/usr/bin/env python3
"""A noisy, a denoised and a reference crop side by side, as one PNG.

    python3 scripts/denoise_figure.py NOISY.exr REFERENCE.exr OUT.png [--crop X,Y,W,H] [--zoom K]

NOISY.exr is a `zvidpt render ... --denoise` image: its RGB is the noisy estimate and its
`denoised.R/G/B` layers the denoiser's output. Each crop is tone mapped the same way (linear
values clamped to [0, 1], the sRGB curve) and enlarged K times (nearest neighbour). Prints
the MSE of the noisy and the denoised image against the reference, whole and in the crop.
Needs `pip install numpy OpenEXR`.
"""
import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bitterli import write_png  # noqa: E402


def channels(path, names):
    import numpy as np
    import OpenEXR
    import Imath
    f = OpenEXR.InputFile(str(path))
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    have = f.header()["channels"].keys()
    missing = [n for n in names if n not in have]
    if missing:
        sys.exit(f"{path}: no {', '.join(missing)} channel (render with --denoise)")
    pt = Imath.PixelType(Imath.PixelType.FLOAT)
    return np.stack([np.frombuffer(f.channel(n, pt), np.float32).reshape(h, w) for n in names], -1).astype(np.float64)


def srgb8(x):
    import numpy as np
    x = np.clip(x, 0.0, 1.0)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(y * 255).astype(np.uint8)


def main():
    import numpy as np
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("noisy", type=Path)
    p.add_argument("reference", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--crop", default=None, help="X,Y,W,H in pixels (default: the middle third)")
    p.add_argument("--zoom", type=int, default=2)
    a = p.parse_args()
    noisy = channels(a.noisy, ["R", "G", "B"])
    denoised = channels(a.noisy, ["denoised.R", "denoised.G", "denoised.B"])
    ref = channels(a.reference, ["R", "G", "B"])
    if noisy.shape != ref.shape:
        sys.exit(f"{a.noisy} is {noisy.shape[1]}x{noisy.shape[0]}, {a.reference} {ref.shape[1]}x{ref.shape[0]}")
    h, w, _ = noisy.shape
    x, y, cw, ch = [int(v) for v in a.crop.split(",")] if a.crop else (w // 3, h // 3, w // 3, h // 3)
    if not (0 <= x < x + cw <= w and 0 <= y < y + ch <= h):
        sys.exit(f"crop {x},{y},{cw},{ch} is not inside the {w}x{h} image")
    crop = lambda img: img[y:y + ch, x:x + cw]
    mse = lambda img, r: float(np.mean((img - r) ** 2))
    for name, img in (("noisy", noisy), ("denoised", denoised)):
        print(f"{name}: MSE {mse(img, ref):.4g} (crop {mse(crop(img), crop(ref)):.4g})")
    gap = 4 * a.zoom
    tiles = [np.kron(srgb8(crop(img)), np.ones((a.zoom, a.zoom, 1), np.uint8)) for img in (noisy, denoised, ref)]
    th, tw, _ = tiles[0].shape
    canvas = np.full((th, 3 * tw + 2 * gap, 3), 255, np.uint8)
    for k, t in enumerate(tiles):
        canvas[:, k * (tw + gap):k * (tw + gap) + tw] = t
    write_png(a.out, canvas.shape[1], canvas.shape[0], canvas.reshape(-1).tobytes())
    print(f"{a.out}: noisy | denoised | reference, crop {x},{y} {cw}x{ch} of {w}x{h}, x{a.zoom}")


if __name__ == "__main__":
    main()
