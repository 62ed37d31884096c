"""zvidpt against Mitsuba 3 on the same scene, at equal time, in one run.

    pip install mitsuba numpy OpenEXR
    python3 peers/race.py SCENE.xml OUT [--time 20] [--seeds 1,2] [--threads 2] [--ref-spp 8192]
        [--integrators "path;zvidpt"] [--zvidpt BIN] [-D NAME=VALUE ...]
    python3 peers/race.py SCENE_DIR OUT [--resolution WxH] [...]

Given SCENE.xml, both renderers read the file itself (zvidpt's Mitsuba importer), so nothing
is translated by hand. Given a zvidpt TOML scene folder of the subset `toml_subset.py` names
(`scenes/cornell-paper`, `cornell-blocks`, `cornell-classic`, `partition`), it is translated
exactly: each OBJ's triangles per material written as a PLY file under OUT/mitsuba/ (face
normals; the winding kept, or reversed where the scene says `reverse_winding`), a `twosided`
`diffuse` of the material's reflectance, an emitter an `area` light of its radiance (Mitsuba's
area lights emit on the front only, as zvidpt's) over a black BSDF, a `perspective` sensor
at `eye` looking at `look_at` with `up` and vertical `fov_y`, an `hdrfilm` with a `box`
filter, the `multijitter` sampler (film points stratified over the pixel, as zvidpt's and
Cycles' are; the `independent` sampler's MSE is 10-17x higher on `cornell-classic`, nearly all
of it on the light's silhouette) and the `path` integrator without a depth limit (Russian
roulette ends paths). For each seed:

- zvidpt renders with each integrator (a `zvidpt render` flag string; `;` between them) for
  --time seconds, training and pre-passes included;
- Mitsuba 3 (`scalar_rgb`, the scene's own integrator, sampler and film, --threads threads)
  renders at the sample count that fills the same time: after a 1-spp warm-up, a 4-spp
  render measures its seconds per sample, and the race render's spp is the budget over that (its own seconds are
  reported; Mitsuba has no time budget of its own).

Every image is compared with a reference, the mean of two `zvidpt reference` renders (`path`
at half --ref-spp each, seeds 1000003 and 1000004, kept in OUT/ref-0.exr and ref-1.exr while
the scene's content hash and spp match): MSE less the reference's own noise (measured from the spread
between the two halves; every MSE against the reference contains it), and
MSE x seconds (lower is better, the figure that equal time cannot make exactly equal). Before any comparison the
translation is checked: the mean of Mitsuba's images against the reference's mean, per
channel, with a z statistic whose variance comes from the spread between Mitsuba's seeds
(per pixel, (a - b)^2 / 2 over two seeds) and the reference's (from its halves); |z| above 4 is
reported as a mismatch and its MSE is not a race result.

Samples per second (zvidpt's own report; Mitsuba's spp × pixels over its seconds) are in the
table too: the path tracers' throughput on the same scene and threads.

Writes OUT/race.csv (a row per renderer, integrator and seed) and OUT/race.md.
"""
import argparse
import csv
import math
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DEFAULT_BIN = HERE.parent / "target" / "release" / "zvidpt"


def read_exr(path):
    """RGB and, where the file has one, the per-pixel variance (zvidpt's `variance` layer)."""
    import OpenEXR

    f = OpenEXR.File(str(path))
    ch = f.parts[0].channels
    if "RGB" in ch:
        rgb = np.asarray(ch["RGB"].pixels, dtype=np.float64)
    elif "RGBA" in ch:
        rgb = np.asarray(ch["RGBA"].pixels, dtype=np.float64)[:, :, :3]
    else:
        rgb = np.dstack([np.asarray(ch[c].pixels, dtype=np.float64) for c in ("R", "G", "B")])
    var = None
    if "variance" in ch:
        var = np.asarray(ch["variance"].pixels, dtype=np.float64)
        if var.ndim == 2:
            var = np.repeat(var[:, :, None], 3, axis=2)
    return rgb, var


def run(args):
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{' '.join(map(str, args))}: {r.stderr.strip()}")
    return r.stdout + r.stderr


def zvidpt_seconds(out):
    m = re.search(r"spp[^,]*, ([0-9.]+) s", out)
    return float(m.group(1)) if m else float("nan")


def zvidpt_samples_per_second(out):
    """zvidpt's own figure of the render's samples per second (training included)."""
    m = re.search(r"([0-9.]+) M samples/s", out)
    return float(m.group(1)) * 1e6 if m else float("nan")


def mitsuba_render(scene, spp, seed):
    import mitsuba as mi

    start = time.perf_counter()
    img = np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)[:, :, :3]
    return img, time.perf_counter() - start


def race_arguments(doc):
    """The command line both races share: scene, output folder, time, seeds, threads, reference
    samples, zvidpt's integrators and binary."""
    p = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene")
    p.add_argument("out")
    p.add_argument("--time", type=float, default=20.0)
    p.add_argument("--seeds", default="1,2")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--ref-spp", type=int, default=8192)
    p.add_argument("--integrators", default="path;zvidpt")
    p.add_argument("--zvidpt", default=str(DEFAULT_BIN))
    return p


def references(zvidpt, scene, out, ref_spp, extra):
    """Two `zvidpt reference` renders of half `ref_spp` each, independent (seeds apart from the
    races'), kept as OUT/ref-0.exr and ref-1.exr while up to date: their mean is the reference,
    and their spread measures its own noise, which every MSE against it contains. Returns the
    reference, the per-pixel variance of its mean, and that variance's mean (the noise)."""
    halves = []
    for k in (0, 1):
        ref_path = out / f"ref-{k}.exr"
        run([zvidpt, "reference", scene, "--spp", max(1, ref_spp // 2), "--seed", 1_000_003 + k, "-o", ref_path,
             "-q", *extra])
        halves.append(read_exr(ref_path)[0])
    ref = (halves[0] + halves[1]) / 2
    # Per pixel, (a - b)^2 / 4 estimates the variance of the mean of two independent renders.
    ref_pixel_var = (halves[0] - halves[1]) ** 2 / 4
    return ref, ref_pixel_var, float(ref_pixel_var.mean())


def race_zvidpt(zvidpt, scene, out, integrators, seeds, seconds, extra, ref, ref_noise):
    """zvidpt with each integrator (`;` between flag strings) and seed for `seconds`: a row
    (renderer, integrator, seed, seconds, MSE less the reference's noise, samples per second)
    per render."""
    rows = []
    for flags in [f.split() for f in integrators.split(";") if f.strip()]:
        name = " ".join(flags)
        for seed in seeds:
            img = out / f"zvidpt-{'-'.join(flags).lstrip('-')}-{seed}.exr"
            o = run([zvidpt, "render", scene, "--integrator", *flags, "--time", seconds, "--seed", seed, "-o", img,
                     "--no-png", *extra])
            rgb, _ = read_exr(img)
            secs = zvidpt_seconds(o)
            mse = float(((rgb - ref) ** 2).mean()) - ref_noise
            rows.append(("zvidpt", name, seed, secs, mse, zvidpt_samples_per_second(o)))
            print(f"zvidpt {name} seed {seed}: {secs:.2f} s, MSE {mse:.4g}", flush=True)
    return rows


def translation_check(images, ref, ref_pixel_var):
    """A peer's mean image over its seeds against the reference's mean, per channel: whether
    |z| < 4 on every channel, the ratios and the z (variance from the spread between the first
    two seeds, per pixel (a - b)^2 / 2, and from the reference's halves)."""
    mean = np.mean(images, axis=0)
    pixels = mean.shape[0] * mean.shape[1]
    if len(images) >= 2:
        spread = ((images[0] - images[1]) ** 2 / 2).sum(axis=(0, 1)) / pixels**2 / len(images)
    else:
        spread = np.zeros(3)
    ref_var_mean = ref_pixel_var.sum(axis=(0, 1)) / pixels**2
    diff = mean.mean(axis=(0, 1)) - ref.mean(axis=(0, 1))
    z = diff / np.sqrt(np.maximum(spread + ref_var_mean, 1e-30))
    ratio = mean.mean(axis=(0, 1)) / np.maximum(ref.mean(axis=(0, 1)), 1e-30)
    return bool(np.all(np.abs(z) < 4.0)), ratio, z


def write_results(out, name, rows, preamble, mismatched):
    """OUT/NAME.csv (a row per render) and OUT/NAME.md (`preamble`, then a row per renderer and
    integrator: means over the seeds; `mismatched` (renderer, integrator) pairs are marked)."""
    with open(out / f"{name}.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["renderer", "integrator", "seed", "seconds", "mse", "samples_per_second", "mse_x_seconds"])
        for r in rows:
            w.writerow([*r, r[3] * r[4]])
    lines = [
        preamble,
        "",
        "| renderer | integrator | seconds | samples/s | MSE | MSE x seconds | spread of MSE x seconds over seeds |",
        "|---|---|---|---|---|---|---|",
    ]
    groups = {}
    for r in rows:
        groups.setdefault((r[0], r[1]), []).append(r)
    for (renderer, integrator), rs in groups.items():
        secs = sum(r[3] for r in rs) / len(rs)
        mse = sum(r[4] for r in rs) / len(rs)
        ms = [r[3] * r[4] for r in rs]
        flag = " (translation mismatch)" if (renderer, integrator) in mismatched else ""
        rate = sum(r[5] for r in rs) / len(rs)
        rate = f"{rate / 1e6:.2f} M" if math.isfinite(rate) else "-"
        lines.append(f"| {renderer} | {integrator}{flag} | {secs:.2f} | {rate} | {mse:.4g} | "
                     f"{sum(ms) / len(ms):.4g} | {min(ms):.4g} - {max(ms):.4g} |")
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    if not all(math.isfinite(r[4]) for r in rows):
        sys.exit("a render produced a non-finite MSE")


def write_ply(path, triangles):
    """An ASCII PLY file of unshared triangles."""
    lines = ["ply", "format ascii 1.0", f"element vertex {3 * len(triangles)}", "property float x",
             "property float y", "property float z", f"element face {len(triangles)}",
             "property list uchar int vertex_indices", "end_header"]
    lines += [" ".join(f"{c:.9g}" for c in p) for tri in triangles for p in tri]
    lines += [f"3 {3 * k} {3 * k + 1} {3 * k + 2}" for k in range(len(triangles))]
    path.write_text("\n".join(lines) + "\n")


def mitsuba_scene_dict(folder, out, width, height):
    """The TOML scene of `toml_subset`'s subset as a Mitsuba 3 scene dictionary (see above)."""
    import mitsuba as mi

    import toml_subset

    peer = "Mitsuba 3"
    cam, materials, meshes = toml_subset.read_scene(folder, peer)
    meshes_dir = out / "mitsuba"
    meshes_dir.mkdir(exist_ok=True)

    def rgb(v):
        return {"type": "rgb", "value": [float(x) for x in v]}

    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": -1},
        "sensor": {
            "type": "perspective",
            "fov": float(cam["fov_y"]),
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["eye"], target=cam["look_at"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": width or cam["width"], "height": height or cam["height"],
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            # Stratified film points, as zvidpt's and Cycles' are: with `independent` the
            # light's silhouette alone gave 10-17x the MSE (cornell-classic, 128x96, 256 spp).
            "sampler": {"type": "multijitter"},
        },
    }
    for k, mesh in enumerate(meshes):
        obj_path = folder / mesh["obj"]
        kd = toml_subset.mtl_colours(obj_path, peer)
        groups = toml_subset.obj_groups(obj_path, mesh.get("reverse_winding", False), peer)
        for g, (name, triangles) in enumerate(groups.items()):
            material = mesh.get("material", name)
            diffuse, emission = toml_subset.surface(materials, kd, mesh, name, peer)
            ply = meshes_dir / f"{k}-{g}-{material}.ply"
            write_ply(ply, triangles)
            shape = {"type": "ply", "filename": str(ply), "face_normals": True}
            if max(emission) > 0:
                shape["emitter"] = {"type": "area", "radiance": rgb(emission)}
                shape["bsdf"] = {"type": "diffuse", "reflectance": rgb([0.0] * 3)}
            else:
                shape["bsdf"] = {"type": "twosided", "material": {"type": "diffuse", "reflectance": rgb(diffuse)}}
            d[f"shape-{k}-{g}"] = shape
    return d


def race_mitsuba(load, seeds, seconds, threads, ref, ref_pixel_var, ref_noise):
    """Mitsuba 3 (`scalar_rgb`, `threads` threads) on the scene `load(mi)` returns, for each seed
    at the sample count that fills `seconds` (measured by a 4-spp render after a 1-spp
    warm-up): its rows (as `race_zvidpt`'s, samples per second from spp × pixels over its
    seconds), whether its mean image matches the reference's, and that check's sentence."""
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(threads)
    scene = load(mi)
    mitsuba_render(scene, 1, 0)  # warm-up: the first render pays for set-up
    _, t4 = mitsuba_render(scene, 4, 0)
    spp = max(1, int(seconds / (t4 / 4)))
    pixels = ref.shape[0] * ref.shape[1]
    rows, images = [], []
    for seed in seeds:
        img, secs = mitsuba_render(scene, spp, seed)
        if img.shape != ref.shape:
            sys.exit(f"Mitsuba rendered {img.shape}, the reference is {ref.shape}")
        images.append(img)
        mse = float(((img - ref) ** 2).mean()) - ref_noise
        rows.append(("mitsuba", f"path {spp} spp", seed, secs, mse, spp * pixels / secs))
        print(f"mitsuba path {spp} spp seed {seed}: {secs:.2f} s, MSE {mse:.4g}", flush=True)
    # The translation check: Mitsuba's mean image against the reference's, per channel.
    matched, ratio, z = translation_check(images, ref, ref_pixel_var)
    check = (f"Mitsuba 3 mean / reference mean: {ratio[0]:.4f}, {ratio[1]:.4f}, {ratio[2]:.4f} "
             f"(z {z[0]:.2f}, {z[1]:.2f}, {z[2]:.2f}): {'matches' if matched else 'MISMATCH'}")
    print(check, flush=True)
    return rows, matched, check


def main():
    p = race_arguments(__doc__)
    p.add_argument("-D", dest="defines", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--resolution", default=None, help="WxH, for a TOML scene folder (default: the scene's)")
    a = p.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in a.seeds.split(",")]
    toml = Path(a.scene).is_dir() and (Path(a.scene) / "scene.toml").is_file()
    if a.resolution and not toml:
        sys.exit("peers/race.py: --resolution is for a TOML scene folder (a Mitsuba file: -D for its film's size)")
    if a.defines and toml:
        sys.exit("peers/race.py: -D is for a Mitsuba file")
    defines = [x for d in a.defines for x in ("-D", d)]
    extra = ["--threads", str(a.threads), *defines]
    width = height = None
    if a.resolution:
        width, height = (int(x) for x in a.resolution.lower().split("x"))
        extra += ["--resolution", a.resolution]
    ref, ref_pixel_var, ref_noise = references(a.zvidpt, a.scene, out, a.ref_spp, extra)
    rows = race_zvidpt(a.zvidpt, a.scene, out, a.integrators, seeds, a.time, extra, ref, ref_noise)

    if toml:
        load = lambda mi: mi.load_dict(mitsuba_scene_dict(Path(a.scene), out, width, height))  # noqa: E731
    else:
        params = dict(d.split("=", 1) for d in a.defines)
        load = lambda mi: mi.load_file(a.scene, **params)  # noqa: E731
    mitsuba_rows, matched, check = race_mitsuba(load, seeds, a.time, a.threads, ref, ref_pixel_var, ref_noise)
    rows += mitsuba_rows
    preamble = (f"Equal time {a.time:g} s, {a.threads} threads, seeds {a.seeds}; MSE against `zvidpt reference` "
                f"(path, {a.ref_spp} spp in two independent halves) less the reference's own noise ({ref_noise:.3g}, "
                f"from the halves' spread). {check}.")
    mismatched = set() if matched else {r[:2] for r in mitsuba_rows}
    write_results(out, "race", rows, preamble, mismatched)


if __name__ == "__main__":
    main()
