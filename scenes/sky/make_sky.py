"""Writes sky.exr, the sky scene's environment map (256×128, equirectangular, +y up): a blue
sky brightening towards the horizon, brown ground below it, and a sun 2.5° in radius, 35°
above the horizon towards −x, +z. Needs numpy and OpenEXR (pip install numpy OpenEXR)."""
import Imath
import numpy as np
import OpenEXR

w, h = 256, 128
j, i = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
theta = (j + 0.5) / h * np.pi  # from the zenith
phi = (i + 0.5) / w * 2 * np.pi  # u = atan2(x, -z) / 2π
dx, dy, dz = np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)
up = np.clip(dy, 0, 1)
sky = np.stack([0.25 + 0.35 * (1 - up), 0.45 + 0.3 * (1 - up), 0.95 - 0.2 * (1 - up)], -1) * 1.2
ground = np.array([0.30, 0.26, 0.20]) * np.ones_like(sky)
img = np.where((dy > 0)[..., None], sky, ground * np.clip(-dy * 3, 0.3, 1)[..., None])
sun = np.array([-0.55, np.sin(np.radians(35)), 0.6])
sun /= np.linalg.norm(sun)
img[dx * sun[0] + dy * sun[1] + dz * sun[2] > np.cos(np.radians(2.5))] = [900.0, 780.0, 600.0]
img = img.astype(np.float32)
header = OpenEXR.Header(w, h)
header["channels"] = {c: Imath.Channel(Imath.PixelType(Imath.PixelType.FLOAT)) for c in "RGB"}
header["compression"] = Imath.Compression(Imath.Compression.ZIP_COMPRESSION)
out = OpenEXR.OutputFile("sky.exr", header)
out.writePixels({c: img[..., k].tobytes() for k, c in enumerate("RGB")})
out.close()
