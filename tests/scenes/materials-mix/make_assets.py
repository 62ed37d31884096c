"""Writes the textured test assets of materials-mix: `tiles.png` (8x8 sRGB colours) and
`vault.obj` (a half cylinder of 4 facets with smooth vertex normals and texture coordinates) and
`tilted.obj` (a floor tile whose normals lean towards the red wall)."""
import math, struct, zlib

def png(path, w, h, rgb):
    raw = b"".join(b"\x00" + bytes(rgb[y * w * 3:(y + 1) * w * 3]) for y in range(h))
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))

pix = []
for y in range(8):
    for x in range(8):
        pix += [40 + 27 * x, 230 - 25 * y, 60 + 120 * ((x + y) % 2)]
png("tiles.png", 8, 8, pix)

# A half cylinder: axis along x, its outside facing up (+y), forward (+z) and down.
n = 4
lines = ["# Half cylinder with smooth normals and texture coordinates (make_assets.py)."]
for i in range(n + 1):
    a = math.pi * i / n
    y, z = math.cos(a), math.sin(a)
    for x in (1.0, -1.0):
        # Placed in the box: radius 0.3, half length 0.3, centred at (-0.4, 0.4, -0.6).
        lines.append(f"v {0.3 * x - 0.4:.6f} {0.3 * y + 0.4:.6f} {0.3 * z - 0.6:.6f}")
    lines.append(f"vn 0 {y:.6f} {z:.6f}")
    for v in (0.0, 1.0):
        lines.append(f"vt {i / n:.6f} {v:.6f}")
for i in range(n):
    a, b = 2 * i + 1, 2 * (i + 1) + 1  # bottom vertices of columns i, i+1 (1-based)
    na, nb = i + 1, i + 2
    # Counter-clockwise seen from outside (+z side).
    lines.append(f"f {a}/{a}/{na} {a + 1}/{a + 1}/{na} {b + 1}/{b + 1}/{nb} {b}/{b}/{nb}")
open("vault.obj", "w").write("\n".join(lines) + "\n")

# A floor tile whose vertex normals all lean 40 degrees towards the red wall (-x): shading
# normals that differ from the geometric one the same way everywhere, so that a weight using
# the wrong cosine does not average out across the tile.
s, c = math.sin(math.radians(40)), math.cos(math.radians(40))
tile = ["# Floor tile with leaning vertex normals (make_assets.py)."]
for x, z in ((0.05, 0.68), (0.05, 0.98), (0.6, 0.98), (0.6, 0.68)):
    tile.append(f"v {x:.6f} -0.999 {z:.6f}")
tile.append(f"vn {-s:.6f} {c:.6f} 0")
tile.append("f 1//1 2//1 3//1 4//1")
open("tilted.obj", "w").write("\n".join(tile) + "\n")
