"""Mitsuba 3's own render of a scene, as the reference the importer's test compares with.

    pip install mitsuba OpenEXR numpy
    python3 reference.py box.xml 4096 16 box-mitsuba.exr
    python3 reference.py box.xml 1024 16 box-mitsuba-depth3.exr max_depth=3

renders the scene `seeds` times at `spp` samples per pixel (scalar_rgb variant, seeds
0..seeds-1), and writes the mean image (R, G, B) with the variance of that mean per pixel
(variance.R/G/B: the sample variance over the renders divided by their number), read by
tests/mitsuba.rs as an image of "1 sample" with that variance.
"""
import sys
import time

import Imath
import mitsuba as mi
import numpy as np
import OpenEXR

mi.set_variant("scalar_rgb")
path, spp, seeds, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
# Further arguments NAME=VALUE are the scene's parameters (Mitsuba's -D).
scene = mi.load_file(path, **dict(a.split("=", 1) for a in sys.argv[5:]))
start = time.time()
images = np.stack([np.array(mi.render(scene, spp=spp, seed=s))[:, :, :3] for s in range(seeds)])
mean = images.mean(0)
var_mean = images.var(0, ddof=1) / seeds
h, w, _ = mean.shape
header = OpenEXR.Header(w, h)
channel = Imath.Channel(Imath.PixelType(Imath.PixelType.FLOAT))
names = ["R", "G", "B", "variance.R", "variance.G", "variance.B"]
header["channels"] = {n: channel for n in names}
planes = [mean[:, :, c] for c in range(3)] + [var_mean[:, :, c] for c in range(3)]
exr = OpenEXR.OutputFile(out, header)
exr.writePixels({n: p.astype(np.float32).tobytes() for n, p in zip(names, planes)})
exr.close()
print(f"{seeds} x {spp} spp in {time.time() - start:.0f} s; image mean {mean.mean(axis=(0, 1))}")
