"""A benchmark suite: a folder of scenes x integrators at equal time against per-scene
references, as one table.

    python3 scripts/suite.py SCENES OUT [--time 20] [--resolution 160x90 | --downscale 8] [--ref-spp 4096]
        [--seeds 1,2] [--integrators "path;zvidpt;jensen --learned-guide on"] [--seed-pairs] [--zvidpt BIN]

SCENES is a folder of scene folders; each is a scene zvidpt opens (scene.toml, scene.xml or
scene.pbrt inside, or pbrt/scene-v4.pbrt as in Bitterli's collection). For each scene:

1. a reference: two `zvidpt reference` renders (`path`) of half --ref-spp each, seeds 1000003
   and 1000004 (OUT/refs/NAME-0.exr, NAME-1.exr; kept and reused while the scene's content hash and spp
   match); their mean is the reference and their spread its noise, which is taken out of
   every MSE (`zvidpt diff IMAGE REF0 REF1`: "MSE less it");
2. every integrator (a `zvidpt render` flag string; `;` between them) for --time seconds per
   seed, its MSE against the reference (`zvidpt diff`).

With --seed-pairs no reference is rendered: each integrator's MSE is its variance, measured
from its own renders taken in pairs of seeds (1 and 2, 3 and 4, ...): half the mean squared
difference of the two images. Every integrator here is unbiased, so its MSE is its variance,
and the pair's estimate of it is unbiased too; it holds no reference noise to take out. A
row then stands for a pair (seed "1+2"), and the brightest pixels are the second image's.

Writes OUT/suite.csv (a row per scene, integrator and seed: seconds, spp, MSE less the reference's
own noise, the plain MSE, relMSE, both without the worst 0.1% of pixels, and the MSE of the
reference's brightest 0.3% of pixels and of the rest, which add up to the first), OUT/suite.md (per
scene the mean MSE of each integrator, its ratio to the first one's, the same ratio of the trimmed MSE, and the geometric means of the
ratios over the scenes, the MSE ratios' with their standard error as a factor, ×/÷, from the
seeds' spread), and OUT/suite.png (MSE per scene and
integrator, log scale) when matplotlib is installed. Equal time means equal wall-clock
seconds of rendering on the same machine and threads, training and pre-passes included.
"""
import argparse
import csv
import math
import re
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
# The share of each reference's pixels, brightest first, reported apart (`zvidpt diff --bright`).
BRIGHT = "0.003"
DEFAULT_BIN = HERE.parent / "target" / "release" / "zvidpt"


def scene_file(d):
    for name in ("scene.toml", "scene.xml", "scene.pbrt", "pbrt/scene-v4.pbrt"):
        if (d / name).is_file():
            return d / name
    return None


def resolution(f, default, downscale):
    """The scene's own size over `downscale`: its Tungsten render's where it has one (the
    collection's files sometimes cut the film: cornell-box states 64x64), else a pbrt film's."""
    tungsten = f.parent / "TungstenRender.exr"
    if downscale and tungsten.is_file():
        try:
            import OpenEXR
            dw = OpenEXR.InputFile(str(tungsten)).header()["dataWindow"]
            w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
            return f"{max(1, w // downscale)}x{max(1, h // downscale)}"
        except ImportError:
            pass
    if downscale and f.suffix == ".pbrt":
        text = f.read_text(errors="replace")
        xs = re.search(r'"integer xresolution"\s*\[?\s*(\d+)', text)
        ys = re.search(r'"integer yresolution"\s*\[?\s*(\d+)', text)
        if xs and ys:
            return f"{max(1, int(xs.group(1)) // downscale)}x{max(1, int(ys.group(1)) // downscale)}"
    return default


def run(args):
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if r.returncode != 0:
        err = [l for l in r.stderr.splitlines() if l.startswith("error:")]
        raise RuntimeError(err[-1] if err else r.stderr.strip()[-300:])
    return r.stdout


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenes")
    p.add_argument("out")
    p.add_argument("--time", type=float, default=20)
    p.add_argument("--resolution", default="160x90")
    p.add_argument("--downscale", type=int, default=0,
                   help="pbrt scenes: their film size over this factor instead of --resolution")
    p.add_argument("--ref-spp", type=int, default=4096)
    p.add_argument("--seeds", default="1,2")
    p.add_argument("--integrators", default="path;zvidpt;jensen --learned-guide on")
    p.add_argument("--only", help="comma-separated scene names")
    p.add_argument("--max-depth", type=int, default=0,
                   help="every render's and the reference's depth in segments (the learned integrator has no "
                        "depth limit: give one this large to compare unbiased images of the same light)")
    p.add_argument("--seed-pairs", action="store_true",
                   help="no reference: each integrator's MSE is its variance over pairs of seeds (an even count)")
    p.add_argument("--reference-integrator", default="path",
                   help="the integrator of the references (any unbiased one; `zvidpt` splits a light smaller "
                        "than a pixel over its film points, which `path` at 4096 spp does not converge); "
                        "a reference already in OUT/refs is kept")
    p.add_argument("--zvidpt", default=str(DEFAULT_BIN))
    a = p.parse_args()
    out = Path(a.out)
    (out / "refs").mkdir(parents=True, exist_ok=True)
    integrators = [s.strip() for s in a.integrators.split(";") if s.strip()]
    seeds = [s.strip() for s in a.seeds.split(",") if s.strip()]
    if a.seed_pairs and (len(seeds) < 2 or len(seeds) % 2):
        p.error("--seed-pairs takes an even number of seeds")
    only = set(a.only.split(",")) if a.only else None
    rows = []
    scenes = []
    for d in sorted(Path(a.scenes).iterdir()):
        f = scene_file(d) if d.is_dir() else None
        if f is None or (only and d.name not in only):
            continue
        name = d.name
        res = resolution(f, a.resolution, a.downscale)
        # Two references of half the samples each, independent (seeds apart from the renders'): their mean is
        # the reference, and their spread measures its noise, which `zvidpt diff` takes out of
        # every MSE.
        refs = [out / "refs" / f"{name}-{k}.exr" for k in (0, 1)]
        half = max(1, a.ref_spp // 2)
        depth = ["--max-depth", a.max_depth] if a.max_depth else []
        try:
            for k, ref in enumerate(refs):
                if a.seed_pairs:
                    break
                if depth or a.reference_integrator != "path":
                    # `reference` keeps the scene's depth: a render of that depth instead.
                    if not ref.exists():
                        run([a.zvidpt, "render", f, "--integrator", *a.reference_integrator.split(), "--spp", half, "--seed",
                             1_000_003 + k, "--resolution", res, *depth, "-o", ref, "--no-png", "-q"])
                else:
                    run([a.zvidpt, "reference", f, "--spp", half, "--seed", 1_000_003 + k, "--resolution", res,
                         "-o", ref, "-q"])
        except RuntimeError as e:
            print(f"{name}: reference failed: {e}", file=sys.stderr)
            continue
        scenes.append(name)
        for integ in integrators:
            tag = re.sub(r"[^A-Za-z0-9]+", "-", integ).strip("-")
            done = []
            for seed in seeds:
                img = out / name / f"{tag}-{seed}.exr"
                img.parent.mkdir(parents=True, exist_ok=True)
                try:
                    line = run([a.zvidpt, "render", f, "--integrator", *integ.split(),
                                "--time", a.time, "--seed", seed, "--resolution", res, *depth, "-o", img, "--no-png"])
                    # The status line: "SCENE WxH, N spp ..., T s, ... -> FILE".
                    status = next(l for l in line.splitlines() if " -> " in l)
                    m = re.search(r"(\d+) spp.*?, ([\d.]+) s\b", status)
                    if a.seed_pairs:
                        done.append((seed, img, m))
                        if len(done) < 2:
                            continue
                        (s0, first, m0), (seed, img, m) = done
                        done = []
                        d = run([a.zvidpt, "diff", first, img, "--bright", BRIGHT])
                        # Half the squared difference of two independent renders: one's variance.
                        scale = 0.5
                        seed = f"{s0}+{seed}"
                        seconds = (float(m0.group(2)) + float(m.group(2))) / 2
                        spp = (int(m0.group(1)) + int(m.group(1))) // 2
                    else:
                        d = run([a.zvidpt, "diff", img, *refs, "--bright", BRIGHT])
                        scale = 1.0
                        seconds, spp = float(m.group(2)), int(m.group(1))
                    mse, rel = re.search(r"MSE (\S+)\s+relMSE (\S+)", d).groups()
                    raw = mse
                    if not a.seed_pairs:
                        mse = re.search(r"MSE less it (\S+)", d).group(1)
                    tmse, trel = re.search(r"pixels: MSE (\S+)\s+relMSE ([^\s)]+)", d).groups()
                    top, rest = re.search(r"pixels: MSE (\S+)\s+the rest: MSE (\S+)", d).groups()
                    figures = dict(mse=mse, mse_raw=raw, relmse=rel, mse_trimmed=tmse, relmse_trimmed=trel,
                                   mse_bright=top, mse_rest=rest)
                    rows.append(dict(scene=name, integrator=integ, seed=seed, seconds=f"{seconds:g}", spp=spp,
                                     **{k: scale * float(v) for k, v in figures.items()}))
                    print(f"{name} | {integ} | seed {seed}: MSE {rows[-1]['mse']:.4g} ({spp} spp)", flush=True)
                except RuntimeError as e:
                    print(f"{name} | {integ} | seed {seed}: failed: {e}", file=sys.stderr)
                    done = []
    with open(out / "suite.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["scene", "integrator", "seed", "seconds", "spp", "mse", "mse_raw", "relmse",
                                           "mse_trimmed", "relmse_trimmed", "mse_bright", "mse_rest"])
        w.writeheader()
        w.writerows(rows)
    def means(key):
        m = {}
        for r in rows:
            m.setdefault((r["scene"], r["integrator"]), []).append(r[key])
        return {k: sum(v) / len(v) for k, v in m.items()}

    mean, rest = means("mse"), means("mse_rest")
    # The seeds' spread: the standard error of each mean MSE (one render's MSE is heavy-tailed
    # where a light smaller than a pixel is seen: a few seeds decide little there).
    spread = {}
    for r in rows:
        spread.setdefault((r["scene"], r["integrator"]), []).append(r["mse"])
    spread = {k: (math.sqrt(sum((x - sum(v) / len(v)) ** 2 for x in v) / (len(v) - 1) / len(v)) if len(v) > 1
                  else None) for k, v in spread.items()}

    def mse_cell(s, i):
        if (s, i) not in mean:
            return "-"
        se = spread[(s, i)]
        return f"{mean[(s, i)]:.4g}" + (f" ± {se:.2g}" if se is not None else "")
    base = integrators[0]
    others = integrators[1:]
    how = (f"seeds {a.seeds}; MSE as each integrator's variance, half the squared difference of its renders "
           f"in pairs of seeds (no reference: every integrator is unbiased), mean over the pairs ± its standard "
           f"error" if a.seed_pairs else
           f"seeds {a.seeds}; MSE against `path` at {a.ref_spp} spp less the reference's own noise (measured "
           f"from two independent halves), mean over the seeds ± its standard error")
    whose = "the second render's; " if a.seed_pairs else ""
    lines = [f"Equal time {a.time:g} s per render, {a.resolution if not a.downscale else f'film / {a.downscale}'}, "
             f"{how}; ratio = {base}'s MSE / "
             f"the integrator's (above 1: better than {base}); rest: the same ratio without the reference's "
             f"brightest {100 * float(BRIGHT):g}% of pixels ({whose}lights smaller than a pixel seen directly, whose error is "
             f"the pixel footprint's and falls with samples per second alone).", "",
             "| " + " | ".join(["scene"] + [f"{i} MSE" for i in integrators] + [f"{base} / {i}" for i in others]
                               + [f"{base} / {i}, rest" for i in others]) + " |",
             "|---|" + "---|" * (len(integrators) + 2 * len(others))]
    logs = {(i, k): [] for k in ("mse", "rest") for i in others}
    log_var = {i: [] for i in others}

    def ratio(table, s, i, k):
        # Less the reference's noise, an MSE can come out at or below zero: no ratio then.
        if (s, i) in table and (s, base) in table and table[(s, i)] > 0 and table[(s, base)] > 0:
            r = table[(s, base)] / table[(s, i)]
            logs[(i, k)].append(math.log(r))
            if k == "mse" and spread.get((s, i)) is not None and spread.get((s, base)) is not None:
                # The log ratio's variance, to first order, from the two means' standard errors.
                log_var[i].append((spread[(s, base)] / table[(s, base)]) ** 2 + (spread[(s, i)] / table[(s, i)]) ** 2)
            return f"{r:.2f}"
        return "-"

    for s in scenes:
        cells = [mse_cell(s, i) for i in integrators]
        cells += [ratio(mean, s, i, "mse") for i in others] + [ratio(rest, s, i, "rest") for i in others]
        lines.append(f"| {s} | " + " | ".join(cells) + " |")
    def geo_cell(key, v):
        if not v:
            return "-"
        cell = f"{math.exp(sum(v) / len(v)):.2f}"
        var = log_var.get(key[0]) if key[1] == "mse" else None
        if var and len(var) == len(v):
            # The geometric mean's standard error, as a factor (its log's: √Σ var / n).
            cell += f" ×/÷ {math.exp(math.sqrt(sum(var)) / len(v)):.2f}"
        return cell
    geo = [geo_cell(key, v) for key, v in logs.items()]
    if others:
        lines.append("| " + " | ".join(["geometric mean"] + [""] * len(integrators) + geo) + " |")
    (out / "suite.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(max(6, len(scenes) * 1.2), 4))
        width = 0.8 / len(integrators)
        for k, i in enumerate(integrators):
            ax.bar([x + k * width for x in range(len(scenes))], [mean.get((s, i), float("nan")) for s in scenes],
                   width, label=i)
        ax.set_yscale("log")
        ax.set_xticks([x + 0.4 - width / 2 for x in range(len(scenes))], scenes, rotation=30, ha="right")
        ax.set_ylabel(f"MSE at {a.time:g} s")
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / "suite.png", dpi=100)
    except ImportError:
        print("(matplotlib not installed: no suite.png)", file=sys.stderr)


if __name__ == "__main__":
    main()
