"""Benedikt Bitterli's rendering resources (pbrt-v4 versions) with zvidpt: which scenes open,
how they compare with Tungsten's renders, and how fast they load.

    pip install numpy OpenEXR
    python3 scripts/bitterli.py probe COLLECTION [--zvidpt BIN]
    python3 scripts/bitterli.py standins COLLECTION STANDINS
    python3 scripts/bitterli.py fidelity COLLECTION OUT [--spp 64] [--scenes a,b] [--zvidpt BIN]
    python3 scripts/bitterli.py load COLLECTION [--scenes a,b] [--zvidpt BIN]
    python3 scripts/bitterli.py tungsten COLLECTION SCENE OUT.exr [--factor 16]

COLLECTION is a folder of scene folders, each holding pbrt/scene-v4.pbrt and
pbrt/TungstenRender.exr (the layout of the public mirror gonsolo/bitterli).

probe     renders every scene at 32x18, 1 spp, and prints a Markdown table: its status (renders,
          or the one error line), the files it names that the copy lacks, and the warnings
          (features approximated or ignored), counted by kind.
standins  makes STANDINS, a copy of COLLECTION (hard links) in which every file a scene names
          but the copy lacks is stood in by a generated one (a grey checkerboard for an image,
          one tiny far-away triangle for a mesh, a few curves for hair), so that incomplete
          scenes can be loaded and timed. A stand-in scene's image means nothing.
fidelity  renders each complete scene with `path` at a quarter of Tungsten's resolution and
          compares it with Tungsten's render averaged down to the same size: per channel, the
          ratio of the image means; per block of 8x8 pixels, a z statistic (below).
tungsten  writes Tungsten's render of SCENE averaged down by a factor, with the estimated
          variance of each averaged pixel (the reference of tests/bitterli.rs).
load      times parsing, BVH builds (both backends where compiled in) and peak memory, from
          the renderer's own report (`--aov` none, `--spp 1`).

The fidelity z statistic: Tungsten's renders are not converged and carry no variance, so the
noise of a Tungsten block mean is estimated from the image itself: half the mean squared
difference of horizontally adjacent pixels (an overestimate where the picture has edges) over
the block's pixel count. Ours is the variance the renderer writes. z = (ours - tungsten) /
sqrt(var_ours + var_tungsten + (1e-4 mean)^2) per block and channel (the floor: emitters seen
directly are noise-free in both); blocks whose Tungsten mean is below 1e-4 of the image mean
are skipped.
"""
import argparse
import os
import re
import shutil
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent
DEFAULT_BIN = HERE.parent / "target" / "release" / "zvidpt"


def scenes(root, only=None):
    out = []
    for d in sorted(Path(root).iterdir()):
        f = d / "pbrt" / "scene-v4.pbrt"
        if f.is_file() and (only is None or d.name in only):
            out.append((d.name, f))
    return out


FILE_RE = re.compile(r'"string filename"\s*\[?\s*"([^"]*)"')
INCLUDE_RE = re.compile(r'^\s*(?:Include|Import)\s+"([^"]*)"', re.M)


def referenced(scene_file):
    """Every file a pbrt scene names (through its includes), relative to its folder."""
    folder = scene_file.parent
    seen, todo, files = set(), [scene_file], []
    while todo:
        f = todo.pop()
        if f in seen or not f.is_file():
            continue
        seen.add(f)
        text = f.read_text(errors="replace")
        # Comments out (a '#' outside strings is rare in these files; strings hold no '#').
        text = "\n".join(line.split("#", 1)[0] for line in text.splitlines())
        for name in INCLUDE_RE.findall(text):
            p = folder / name
            files.append(p)
            todo.append(p)
        # The film's output name is not an input: drop the Film directive's parameters.
        text = re.sub(r"^\s*Film\b.*?(?=^\s*[A-Z][A-Za-z]+\b)", "", text, flags=re.M | re.S)
        for name in FILE_RE.findall(text):
            files.append(folder / name)
    return list(dict.fromkeys(files))


def missing(scene_file):
    return [p for p in referenced(scene_file) if not p.exists()]


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, **kw)


def cmd_probe(a):
    print("| scene | status | files missing from the copy | warnings |")
    print("|---|---|---|---|")
    for name, f in scenes(a.collection):
        gone = missing(f)
        t0 = time.time()
        r = run([a.zvidpt, "render", str(f), "--integrator", "path", "--resolution", "32x18", "--spp", "1",
                 "-q", "--no-png", "-o", f"/tmp/bitterli-probe-{name}.exr"], timeout=1800)
        secs = time.time() - t0
        lines = r.stderr.strip().splitlines()
        warnings = {}
        for line in lines:
            if line.startswith("warning:"):
                # The warning's text without its file and line.
                kind = re.sub(r"^warning: (\S+:\d+: )?", "", line)
                kind = re.sub(r"\d+", "N", kind)
                warnings[kind] = warnings.get(kind, 0) + 1
        if r.returncode == 0:
            status = f"renders ({secs:.1f} s)"
        else:
            err = [l for l in lines if l.startswith("error:")]
            status = err[-1].replace(str(Path(a.collection).resolve()) + "/", "").replace("|", "/") if err else "failed"
        miss = ", ".join(str(p.relative_to(f.parent)) for p in gone[:4]) + (f" (+{len(gone) - 4})" if len(gone) > 4 else "")
        warn = "; ".join(f"{k} (x{v})" if v > 1 else k for k, v in sorted(warnings.items()))
        print(f"| {name} | {status} | {miss or '-'} | {warn or '-'} |", flush=True)


def write_png(path, w, h, rgb):
    raw = b"".join(b"\x00" + bytes(rgb[y * w * 3:(y + 1) * w * 3]) for y in range(h))
    chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def checker(w, h):
    return [v for y in range(h) for x in range(w) for v in ([160] * 3 if (x // 8 + y // 8) % 2 else [96] * 3)]


def stand_in(p):
    """Writes a generated file where `p` is missing."""
    p.parent.mkdir(parents=True, exist_ok=True)
    ext = p.suffix.lower()
    if ext == ".tga":
        w = h = 64
        px = checker(w, h)
        p.write_bytes(bytes([0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0]) + struct.pack("<HH", w, h) + bytes([24, 0x20])
                      + bytes(v for i in range(0, len(px), 3) for v in (px[i + 2], px[i + 1], px[i])))
    elif ext in (".png", ".jpg", ".jpeg"):
        write_png(p, 64, 64, checker(64, 64))
    elif ext == ".pfm":
        w, h = 64, 32
        p.write_bytes(f"PF\n{w} {h}\n-1\n".encode() + struct.pack(f"<{w * h * 3}f", *([0.5] * (w * h * 3))))
    elif ext == ".exr":
        import numpy as np
        import OpenEXR
        import Imath
        w, h = 64, 32
        header = OpenEXR.Header(w, h)
        ch = Imath.Channel(Imath.PixelType(Imath.PixelType.FLOAT))
        header["channels"] = {c: ch for c in "RGB"}
        out = OpenEXR.OutputFile(str(p), header)
        plane = np.full((h, w), 0.5, np.float32).tobytes()
        out.writePixels({c: plane for c in "RGB"})
        out.close()
    elif ext == ".ply":
        p.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                     "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                     "1e4 1e4 1e4\n1e4 1e4 1.0001e4\n1e4 1.0001e4 1e4\n3 0 1 2\n")
    elif ext == ".obj":
        p.write_text("v 1e4 1e4 1e4\nv 1e4 1e4 1.0001e4\nv 1e4 1.0001e4 1e4\nf 1 2 3\n")
    elif ext == ".pbrt":
        # Hair: a few hundred curls of four B-spline points near the origin.
        import random
        rng = random.Random(1)
        lines = []
        for _ in range(500):
            x, z = rng.uniform(-1, 1), rng.uniform(-1, 1)
            pts = " ".join(f"{x + 0.05 * k * rng.uniform(-1, 1):.4f} {k * 0.3:.4f} {z:.4f}" for k in range(4))
            lines.append(f'Shape "curve" "string type" [ "cylinder" ] "string basis" [ "bspline" ] "point3 P" [ {pts} ] "float width" [ 0.01 ]')
        p.write_text("\n".join(lines) + "\n")
    else:
        return False
    return True


def cmd_standins(a):
    src, dst = Path(a.collection).resolve(), Path(a.standins).resolve()
    if dst.exists():
        sys.exit(f"{dst} exists: give a new folder")
    shutil.copytree(src, dst, copy_function=os.link)
    for name, f in scenes(dst):
        gone = missing(f)
        # The Mitsuba 3 versions beside some scenes name their files as <string name="filename">.
        xml = f.parent.parent / "mitsuba" / "scene_v3.xml"
        if xml.is_file():
            names = re.findall(r'name="filename"\s+value="([^"]*)"', xml.read_text(errors="replace"))
            gone += [xml.parent / n for n in dict.fromkeys(names) if not (xml.parent / n).exists()]
        for p in gone:
            made = stand_in(p) if p.name and not p.name.startswith(".") else False
            print(f"{name}: {p.relative_to(f.parent.parent)}: {'stood in' if made else 'left missing'}")


def read_exr(path):
    import numpy as np
    import OpenEXR
    import Imath
    f = OpenEXR.InputFile(str(path))
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    names = f.header()["channels"].keys()
    pt = Imath.PixelType(Imath.PixelType.FLOAT)
    get = lambda c: np.frombuffer(f.channel(c, pt), np.float32).reshape(h, w)
    rgb = np.stack([get(c) for c in "RGB"], -1).astype(np.float64)
    var = None
    if all(f"variance.{c}" in names for c in "RGB"):
        var = np.stack([get(f"variance.{c}") for c in "RGB"], -1).astype(np.float64)
    return rgb, var


def cmd_fidelity(a):
    import numpy as np
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    only = set(a.scenes.split(",")) if a.scenes else None
    print("| scene | resolution, spp | ours / Tungsten (R, G, B) | blocks | max abs z | rms z | seconds |")
    print("|---|---|---|---|---|---|---|")
    for name, f in scenes(a.collection, only):
        if missing(f):
            continue
        tung_path = f.parent / "TungstenRender.exr"
        if not tung_path.exists():
            continue
        tung, _ = read_exr(tung_path)
        th, tw, _ = tung.shape
        s = a.factor
        w, h = tw // s, th // s
        # A few Tungsten renders hold non-finite pixels (water-caustic: one inf): left out of
        # the means, and their pixels' blocks out of the z-test.
        bad = ~np.isfinite(tung[:h * s, :w * s]).all(-1).reshape(h, s, w, s).any((1, 3))
        tung = np.where(np.isfinite(tung), tung, 0.0)
        tung = tung[:h * s, :w * s].reshape(h, s, w, s, 3).mean((1, 3))
        ours_path = out / f"{name}.exr"
        t0 = time.time()
        r = run([a.zvidpt, "render", str(f), "--integrator", "path", "--resolution", f"{w}x{h}", "--spp", str(a.spp),
                 "--seed", "1", "-q", "-o", str(ours_path), "--png", str(out / f"{name}.png")] + a.extra.split())
        secs = time.time() - t0
        if r.returncode != 0:
            print(f"| {name} | failed: {r.stderr.strip().splitlines()[-1]} | | | | | |")
            continue
        ours, var = read_exr(ours_path)
        # zvidpt writes the variance of each pixel's mean.
        good = ~bad
        ratio = ours[good].mean(0) / np.maximum(tung[good].mean(0), 1e-12)
        b = a.block
        bh, bw = h // b, w // b
        blk = lambda img: img[:bh * b, :bw * b].reshape(bh, b, bw, b, 3).mean((1, 3))
        ours_b, tung_b = blk(ours), blk(tung)
        var_ours = var[:bh * b, :bw * b].reshape(bh, b, bw, b, 3).sum((1, 3)) / (b * b) ** 2
        d = np.diff(tung[:bh * b, :bw * b], axis=1)
        noise = np.concatenate([d, d[:, -1:]], 1) ** 2 / 2
        var_tung = noise.reshape(bh, b, bw, b, 3).mean((1, 3)) / (b * b)
        keep = (tung_b > 1e-4 * tung.mean()) & ~blk(bad[..., None].repeat(3, -1).astype(float)).astype(bool)
        # A floor of 1e-4 of the block's mean: emitters seen directly are noise-free in both.
        z = (ours_b - tung_b) / np.sqrt(var_ours + var_tung + (1e-4 * tung_b) ** 2 + 1e-30)
        z = z[keep]
        print(f"| {name} | {w}x{h}, {a.spp} | {ratio[0]:.3f}, {ratio[1]:.3f}, {ratio[2]:.3f} | {z.size} | "
              f"{np.abs(z).max():.1f} | {np.sqrt((z ** 2).mean()):.2f} | {secs:.0f} |", flush=True)
        # Side by side for looking: Tungsten (averaged down) above ours, sRGB.
        both = np.concatenate([tung, ours], 0)
        srgb = np.where(both <= 0.0031308, 12.92 * both, 1.055 * np.power(np.maximum(both, 0), 1 / 2.4) - 0.055)
        px = (np.clip(srgb, 0, 1) * 255 + 0.5).astype(np.uint8)
        write_png(out / f"{name}-vs-tungsten.png", w, 2 * h, list(px.reshape(-1)))


def cmd_tungsten(a):
    """Tungsten's render of one scene averaged down by `factor`, with the variance of each
    averaged pixel estimated as for `fidelity` (adjacent-pixel differences), written as an EXR
    that zvidpt's tests read as an image of one sample with that variance."""
    import numpy as np
    import OpenEXR
    import Imath
    tung, _ = read_exr(Path(a.collection) / a.scene / "pbrt" / "TungstenRender.exr")
    tung = np.where(np.isfinite(tung), tung, 0.0)
    th, tw, _ = tung.shape
    s = a.factor
    h, w = th // s, tw // s
    tung = tung[:h * s, :w * s]
    d = np.diff(tung, axis=1)
    noise = np.concatenate([d, d[:, -1:]], 1) ** 2 / 2
    mean = tung.reshape(h, s, w, s, 3).mean((1, 3))
    var = noise.reshape(h, s, w, s, 3).mean((1, 3)) / (s * s)
    header = OpenEXR.Header(w, h)
    ch = Imath.Channel(Imath.PixelType(Imath.PixelType.FLOAT))
    names = ["R", "G", "B", "variance.R", "variance.G", "variance.B"]
    header["channels"] = {n: ch for n in names}
    out = OpenEXR.OutputFile(a.out, header)
    planes = [mean[:, :, c] for c in range(3)] + [var[:, :, c] for c in range(3)]
    out.writePixels({n: p.astype(np.float32).tobytes() for n, p in zip(names, planes)})
    out.close()
    print(f"{a.out}: {w}x{h}, mean {mean.mean((0, 1))}")


def cmd_load(a):
    only = set(a.scenes.split(",")) if a.scenes else None
    print("| scene | triangles | backend | load + build s | peak RSS MiB | samples/s | rays/s |")
    print("|---|---|---|---|---|---|---|")
    for name, f in scenes(a.collection, only):
        for backend in a.backends.split(","):
            t0 = time.time()
            r = run(["/usr/bin/time", "-v", a.zvidpt, "render", str(f), "--integrator", "path", "--resolution",
                     a.resolution, "--spp", str(a.spp), "--backend", backend, "-q", "--no-png", "-o",
                     f"/tmp/bitterli-load-{name}.exr"])
            wall = time.time() - t0
            rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr)
            line = [l for l in r.stderr.splitlines() if " spp, " in l and "samples/s" in l]
            err = [l for l in r.stderr.splitlines() if l.startswith("error:")]
            if r.returncode != 0 or not line:
                print(f"| {name} | | {backend} | {err[-1] if err else 'failed'} | | | |")
                continue
            m = re.search(r"(\d+) spp, ([\d.]+) s, ([\d.]+) M samples/s, ([\d.]+) M rays/s", line[0])
            render_s = float(m.group(2))
            tri = re.search(r"([\d,]+) triangles", r.stderr)
            print(f"| {name} | {tri.group(1) if tri else '?'} | {backend} | {wall - render_s:.1f} | "
                  f"{int(rss.group(1)) / 1024:.0f} | {m.group(3)} M | {m.group(4)} M |", flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("tungsten")
    t.add_argument("collection")
    t.add_argument("scene")
    t.add_argument("out")
    t.add_argument("--factor", type=int, default=16)
    for name in ("probe", "standins", "fidelity", "load"):
        s = sub.add_parser(name)
        s.add_argument("collection")
        s.add_argument("--zvidpt", default=str(DEFAULT_BIN))
        if name == "standins":
            s.add_argument("standins")
        if name == "fidelity":
            s.add_argument("out")
            s.add_argument("--spp", type=int, default=64)
            s.add_argument("--factor", type=int, default=4, help="Tungsten's resolution over ours")
            s.add_argument("--block", type=int, default=8)
            s.add_argument("--extra", default="", help="more zvidpt render flags, e.g. \"--max-depth 65\"")
        if name in ("fidelity", "load"):
            s.add_argument("--scenes")
        if name == "load":
            s.add_argument("--backends", default="bvh")
            s.add_argument("--resolution", default="64x36")
            s.add_argument("--spp", type=int, default=1)
    a = p.parse_args()
    commands = {"probe": cmd_probe, "standins": cmd_standins, "fidelity": cmd_fidelity, "load": cmd_load,
                "tungsten": cmd_tungsten}
    commands[a.command](a)


if __name__ == "__main__":
    main()
