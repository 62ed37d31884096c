#!/usr/bin/env python3
"""Regenerates the results tables (run through scripts/results.sh, which builds the binary).

    python3 scripts/results.py --zvidpt BIN (--quick | --full) [--bitterli COLLECTION]
        [--out DIR] [--write] [--studies cornell-paper,race,suite,cycles]

Four studies; the first, second and fourth are the rows of the README's headline table:

1. cornell-paper (512x384): seconds each integrator needs to reach the MSE of a 256-spp path
   image, learning included. A `zvidpt reference` (path), the target (`zvidpt converge
   --integrators path --spp 256`), then `zvidpt converge --time-to-mse`. The reference's own
   noise adds the same amount to every image's MSE and to the target, so the seconds to the
   target do not depend on it in expectation; --quick therefore takes a 512-spp reference,
   and path's seconds to its own 256-spp error from the target runs themselves.
2. cornell-mitsuba against Mitsuba 3 at equal time (peers/race.py; skipped without pip's
   `mitsuba`).
3. Bitterli's seven complete scenes at equal time (scripts/suite.py; skipped without
   --bitterli or $BITTERLI, the collection's root folder), written to docs/results.md. Its
   figures are heavy-tailed (single-pixel caustic paths decide some scenes' MSE), so eight
   seeds of 8 s and references are needed: --full only, unless named in --studies, when
   --quick measures each integrator's MSE as its variance over pairs of seeds (`suite.py
   --seed-pairs`, 6 s, four seeds; no reference).
4. cornell-paper against Blender's Cycles, path tracing and path guiding, at equal time
   (peers/race_cycles.py; skipped without pip's `bpy`).

--quick runs the headline's studies at the headline's own time budgets and seeds, with
cheaper references (whose noise is taken out of every MSE, so they change no figure in
expectation), and then checks each of its figures against the README's: the ratio of the
two and a z-score from the seeds' spread, within noise where |z| <= 3.

Writes DIR/results.md (default `results`): every table, each with the machine, thread count,
commit and date it was measured on, the headline table and (--quick) the check. --full (and
--quick with --write) also rewrites the generated sections of docs/results.md (between
`<!-- results: NAME -->` markers), docs/suite.png, and the README's headline table.
"""
import argparse
import csv
import datetime
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COMPLETE = ["coffee", "cornell-box", "hair-curl", "veach-bidir", "veach-mis", "volumetric-caustic", "water-caustic"]
MODES = {
    "quick": dict(ttm_ref=512, runs=2, race_time=20, race_seeds="1,2", race_ref=256, suite_time=6, suite_ref=0,
                  suite_seed_pairs=True, suite_seeds="1,2,3,4", suite_integrators="path;zvidpt", cycles_time=20, cycles_ref=256,
                  cycles_integrators="path;zvidpt", studies="cornell-paper,race,cycles"),
    "full": dict(ttm_ref=8192, runs=2, race_time=20, race_seeds="1,2", race_ref=4096, suite_time=8, suite_ref=4096,
                 suite_seed_pairs=False, suite_seeds="1,2,3,4,5,6,7,8", suite_integrators="path;zvidpt;jensen --learned-guide on", cycles_time=20,
                 cycles_ref=8192, cycles_integrators="path;zvidpt;jensen --learned-guide on",
                 studies="cornell-paper,race,suite,cycles"),
}


def run(cmd, log):
    """Runs `cmd`, its output appended to `log`; stops the script with its last lines on failure."""
    print("$ " + " ".join(str(c) for c in cmd), flush=True)
    with open(log, "a") as fh:
        fh.write("$ " + " ".join(str(c) for c in cmd) + "\n")
        fh.flush()
        p = subprocess.run([str(c) for c in cmd], stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT)
    if p.returncode != 0:
        tail = Path(log).read_text().splitlines()[-5:]
        sys.exit(f"failed ({p.returncode}): {' '.join(str(c) for c in cmd)}\n" + "\n".join(tail))


def machine():
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT).stdout.strip()
    # The tables this script rewrites do not make the measured code another commit's.
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", ":!docs", ":!README.md"],
                           capture_output=True, text=True, cwd=ROOT).stdout.strip()
    return dict(cpu=cpu, threads=os.cpu_count(), commit=commit + ("+changes" if dirty else ""),
                date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"))


def stamp(m, mode, seconds):
    return (f"*Measured by `scripts/results.sh --{mode}` on {m['cpu']}, {m['threads']} threads, commit "
            f"{m['commit']}, {m['date']} ({seconds:.0f} s).*")


def rel_se(values):
    """The standard error of the mean of `values` over the mean (nan from fewer than two)."""
    v = [x for x in values if not math.isnan(x)]
    if len(v) < 2 or sum(v) == 0:
        return math.nan
    m = sum(v) / len(v)
    sd = math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1))
    return sd / math.sqrt(len(v)) / abs(m)


def number(text, pattern=r"([0-9]+(?:\.[0-9]*)?(?:e[-+]?[0-9]+)?)"):
    """The first number `pattern` finds in `text` (its first group), or None."""
    m = re.search(pattern, text)
    return float(m.group(1)) if m else None


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def cornell_paper(a, s, out, log):
    """Seconds to the MSE of a 256-spp path image; returns (markdown, headline cells)."""
    t0 = time.time()
    d = out / "cornell-paper"
    d.mkdir(parents=True, exist_ok=True)
    ref = d / f"ref-{s['ttm_ref']}.exr"
    if not ref.exists():
        run([a.zvidpt, "reference", "--spp", s["ttm_ref"], "--seed", "0", "-o", ref], log)
    run([a.zvidpt, "converge", "--reference", ref, "--integrators", "path", "--spp", "256", "--runs", s["runs"],
         "--seed", "1", "-o", d / "target"], log)
    target_rows = [r for r in read_csv(d / "target" / "converge.csv") if r["integrator"] == "path"]
    target = float(target_rows[0]["mse"])
    path_runs = [r for r in read_csv(d / "target" / "runs.csv") if r["integrator"] == "path"]
    integrators = "zvidpt" if a.mode == "quick" else "path,zvidpt"
    run([a.zvidpt, "converge", "--reference", ref, "--integrators", integrators, "--time-to-mse", f"{target:.6g}",
         "--runs", s["runs"], "--seed", "1", "--max-spp", "1024", "-o", d / "ttm"], log)
    ttm = read_csv(d / "ttm" / "time_to_mse.csv")
    seconds = {"path": [float(r["seconds"]) for r in path_runs]} if a.mode == "quick" else {}
    for r in ttm:
        seconds.setdefault(r["integrator"], []).append(float(r["seconds"]) if r["reached"] == "true" else math.nan)
    mean = {k: sum(v) / len(v) for k, v in seconds.items()}
    ratio = mean["zvidpt"] / mean["path"]
    seeds = ", ".join(str(1 + k) for k in range(s["runs"]))
    how = ("path: its 256-spp target renders" if a.mode == "quick" else "path and zvidpt: `zvidpt converge --time-to-mse`")
    lines = [stamp(a.m, a.mode, time.time() - t0), "",
             f"Reference: path at {s['ttm_ref']} spp (`zvidpt reference --spp {s['ttm_ref']} --seed 0`); target: "
             f"the MSE of path at 256 spp, {target:.5g} (mean of seeds {seeds}); seconds from {how}.", "",
             f"| integrator | seconds to MSE {target:.5g} (seeds {seeds}) | ratio to path |", "|---|---|---|"]
    for k in ("path", "zvidpt"):
        cell = ", ".join(f"{x:.2f}" for x in seconds[k])
        lines.append(f"| {k} | {cell} | {'1' if k == 'path' else f'**{ratio:.3f}**'} |")
    head = (f"seconds to the MSE of 256-spp path ({target:.4f}), seeds {seeds}",
            ", ".join(f"{x:.1f}" for x in seconds["path"]),
            "**" + ", ".join(f"{x:.1f}" for x in seconds["zvidpt"]) + f"** ({ratio:.3f}×)", "")
    se = math.hypot(rel_se(seconds["zvidpt"]), rel_se(seconds["path"]))
    checks = [("zvidpt's seconds ÷ path's", ratio, se, lambda cells: number(cells[3], r"\(([0-9.]+)×\)"))]
    return "\n".join(lines), head, checks


def peer_race(a, out, log, modules, what, script, scene, seconds, args, name):
    """Runs a race script of peers/ (None when this Python lacks `modules`); returns its table,
    stamped, and each (renderer, integrator)'s mean MSE x seconds over the seeds."""
    if subprocess.run([sys.executable, "-c", f"import {modules}"], capture_output=True).returncode != 0:
        print(f"(no {modules.replace(', ', '/')} for this Python: the race against {what} is skipped)",
              file=sys.stderr)
        return None
    t0 = time.time()
    d = out / name
    run([sys.executable, "-W", "ignore", script, scene, d, "--time", seconds, *args, "--zvidpt", a.zvidpt], log)
    by = {}
    for r in read_csv(d / f"{name}.csv"):
        by.setdefault((r["renderer"], r["integrator"]), []).append(float(r["mse_x_seconds"]))
    mean = {k: sum(v) / len(v) for k, v in by.items()}
    return stamp(a.m, a.mode, time.time() - t0) + "\n\n" + (d / f"{name}.md").read_text().strip(), mean, by


def race(a, s, out, log):
    """zvidpt against Mitsuba 3 on cornell-mitsuba; None without mitsuba."""
    r = peer_race(a, out, log, "mitsuba, numpy, OpenEXR", "Mitsuba 3", "peers/race.py",
                  "scenes/cornell-mitsuba/scene.xml", s["race_time"],
                  ["--seeds", s["race_seeds"], "--ref-spp", s["race_ref"]], "race")
    if r is None:
        return None
    md, mean, by = r
    mitsuba = [k for k in mean if k[0] != "zvidpt"]
    head = (f"MSE × seconds at {s['race_time']} s", f"{mean[('zvidpt', 'path')]:.4f}",
            f"**{mean[('zvidpt', 'zvidpt')]:.4f}**", f"Mitsuba 3 `path`: {mean[mitsuba[0]]:.4f}" if mitsuba else "")
    checks = ratio_checks(mean, by, [(("zvidpt", "zvidpt"), "`zvidpt`", lambda c: number(c[3]))]
                          + [(k, "Mitsuba 3", lambda c: number(c[4], r"Mitsuba 3 `path`: ([0-9.]+)")) for k in mitsuba])
    return md, head, checks


def ratio_checks(mean, by, figures):
    """Checks of each (key, name, README cell reader) figure as a ratio to our path tracer's
    MSE x seconds in the same run (the absolute figures depend on the machine's speed)."""
    base = ("zvidpt", "path")
    out = []
    for key, name, read in figures:
        se = math.hypot(rel_se(by[key]), rel_se(by[base]))
        out.append((f"{name} ÷ `path`, MSE × s", mean[key] / mean[base], se,
                    lambda c, read=read: (read(c) or math.nan) / (number(c[2]) or math.nan)))
    return out


def cycles(a, s, out, log):
    """zvidpt against Cycles on cornell-paper; None without bpy."""
    r = peer_race(a, out, log, "bpy, numpy, OpenEXR", "Cycles", "peers/race_cycles.py", "scenes/cornell-paper",
                  s["cycles_time"], ["--seeds", "1,2", "--ref-spp", s["cycles_ref"], "--integrators",
                                     s["cycles_integrators"]], "cycles")
    if r is None:
        return None
    md, mean, by = r
    peers = ", ".join(f"Cycles {name}: {v:.4f}" for (renderer, name), v in mean.items() if renderer == "cycles")
    head = (f"MSE × seconds at {s['cycles_time']} s", f"{mean[('zvidpt', 'path')]:.4f}",
            f"**{mean[('zvidpt', 'zvidpt')]:.4f}**", peers)
    checks = ratio_checks(mean, by, [(("zvidpt", "zvidpt"), "`zvidpt`", lambda c: number(c[3]))] + [
        (k, f"Cycles {k[1]}", lambda c, p="Cycles " + re.escape(k[1]) + r": ([0-9.]+)": number(c[4], p))
        for k in mean if k[0] == "cycles"])
    return md, head, checks


def missing_files(scene):
    """The files `scene`'s pbrt-v4 file (and the files it includes) names that are not there
    or are empty: the public mirror of the collection leaves some of its largest files out."""
    main = scene / "pbrt" / "scene-v4.pbrt"
    if not main.is_file():
        return [str(main)]
    lacking, todo, seen = [], [main], set()
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        text = f.read_text(errors="replace")
        for m in re.finditer(r'"string filename"\s*\[?\s*"([^"]+)"|^\s*(?:Include|Import)\s+"([^"]+)"', text, re.M):
            name = m.group(1) or m.group(2)
            directive = re.findall(r"^\s*([A-Z][A-Za-z]+)", text[:m.start()], re.M)
            if m.group(1) and directive and directive[-1] == "Film":
                continue  # the render's output, not an input
            g = main.parent / name
            if not g.is_file() or g.stat().st_size == 0:
                lacking.append(name)
            elif m.group(2) or g.suffix == ".pbrt":
                todo.append(g)
    return lacking


def suite(a, s, out, log):
    """Bitterli's complete scenes at equal time; None without the collection."""
    collection = a.bitterli or os.environ.get("BITTERLI")
    if not collection:
        print("(no --bitterli COLLECTION: the public-scene suite is skipped)", file=sys.stderr)
        return None
    t0 = time.time()
    links = out / "bitterli-scenes"
    links.mkdir(parents=True, exist_ok=True)
    if not Path(collection).is_dir():
        sys.exit(f"{collection}: not a folder (Bitterli's collection, one folder per scene)")
    used = []
    for name in COMPLETE:
        src = Path(collection).resolve() / name
        link = links / name
        if link.is_symlink() or link.exists():
            link.unlink()
        lacking = missing_files(src)
        if lacking:
            print(f"({name}: {len(lacking)} of its files are missing from this copy, e.g. {lacking[0]}: "
                  "left out of the suite)", file=sys.stderr)
            continue
        link.symlink_to(src)
        used.append(name)
    if not used:
        sys.exit(f"{collection}: none of the complete scenes ({', '.join(COMPLETE)}) is there")
    d = out / "suite"
    run([sys.executable, "scripts/suite.py", links, d, "--time", s["suite_time"], "--downscale", "8", "--ref-spp",
         s["suite_ref"], "--seeds", s["suite_seeds"], "--integrators", s["suite_integrators"], "--zvidpt", a.zvidpt,
         *(["--seed-pairs"] if s["suite_seed_pairs"] else [])], log)
    table = (d / "suite.md").read_text().strip()
    rows = [r for r in table.splitlines() if r.startswith("| ") and not r.startswith("| scene")]
    n_int = len(s["suite_integrators"].split(";"))
    def cell(r):
        # "-": an MSE at or below zero once the reference's noise is out (no ratio).
        v = r.strip("|").split("|")[1 + n_int].strip()
        return float(v) if v not in ("", "-") else math.nan

    ahead = sum(1 for r in rows if not r.startswith("| geometric") and cell(r) > 1.0)
    geo = [r for r in rows if r.startswith("| geometric")][0].strip("|").split("|")[1 + n_int].strip()
    seeds = len(s["suite_seeds"].split(","))
    head = (f"path's MSE ÷ the integrator's at {s['suite_time']} s, {seeds} seeds, geometric mean", "1",
            f"{geo} (ahead on {ahead} of {len(used)})", "")
    return stamp(a.m, a.mode, time.time() - t0) + "\n\n" + table, head, d / "suite.png"


def replace_section(path, name, body):
    """Replaces the text between `<!-- results: NAME -->` and `<!-- /results: NAME -->`."""
    text = path.read_text()
    pattern = re.compile(rf"(<!-- results: {re.escape(name)} -->\n).*?(\n?<!-- /results: {re.escape(name)} -->)", re.S)
    if not pattern.search(text):
        sys.exit(f"{path}: no `<!-- results: {name} -->` section")
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(2).lstrip("\n"), text))
    tmp.replace(path)


def replace_headline_rows(path, head):
    """Replaces the README headline's rows of the studies that ran (matched by their first
    cell), keeping the others' rows as they were measured."""
    text = path.read_text()
    m = re.search(r"<!-- results: headline -->\n(.*?)\n<!-- /results: headline -->", text, re.S)
    if not m:
        sys.exit(f"{path}: no `<!-- results: headline -->` section")
    lines = m.group(1).splitlines()
    for row in head:
        new = "| " + " | ".join(row) + " |"
        at = [i for i, line in enumerate(lines) if line.startswith("| " + row[0] + " |")]
        if at:
            lines[at[0]] = new
        else:
            lines.append(new)
    replace_section(path, "headline", "\n".join(lines))


def check_headline(readme, checks):
    """Each figure of this run against the README headline's: their ratio and a z-score of
    its logarithm, whose standard error is this run's (from its seeds' spread) counted twice,
    for the README's measurement of the same settings. Returns a Markdown table."""
    text = readme.read_text()
    m = re.search(r"<!-- results: headline -->\n(.*?)\n<!-- /results: headline -->", text, re.S)
    rows = {}
    for line in (m.group(1).splitlines() if m else []):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 5:
            rows[cells[0]] = cells
    lines = ["| scene | figure | README | this run | ratio | z | |", "|---|---|---|---|---|---|---|"]
    within = total = 0
    for row, what, value, se, extract in checks:
        cells = rows.get(row[0])
        # The same measure (a parenthesised figure aside: the target MSE holds its reference's noise).
        same = cells and re.sub(r"\([^)]*\)", "", cells[1]) == re.sub(r"\([^)]*\)", "", row[1])
        theirs = extract(cells) if same else None
        if theirs is None or not theirs > 0 or not value > 0:
            lines.append(f"| {row[0]} | {what} | (not in the README at these settings) | {value:.4g} | | | |")
            continue
        ratio = value / theirs
        z = math.log(ratio) / (math.sqrt(2) * se) if se > 0 else math.inf
        ok = abs(z) <= 3
        within += ok
        total += 1
        lines.append(f"| {row[0]} | {what} | {theirs:.4g} | {value:.4g} | {ratio:.3f} | {z:+.1f} | "
                     f"{'within noise' if ok else '**outside noise**'} |")
    lines += ["", f"{within} of {total} figures within noise of the README's (|z| <= 3; z from this run's seeds' "
              "spread, counted once for each measurement)."]
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--quick", dest="mode", action="store_const", const="quick")
    g.add_argument("--full", dest="mode", action="store_const", const="full")
    p.add_argument("--zvidpt", required=True)
    p.add_argument("--bitterli", help="Bitterli's collection (its root folder)")
    p.add_argument("--out", default="results")
    p.add_argument("--write", action="store_true", help="with --quick: rewrite the docs too")
    p.add_argument("--studies",
                   help="the studies to run, comma-separated (default: all four with --full; cornell-paper,race,cycles, "
                        "the headline's, with --quick); --full rewrites the README's headline rows of the studies that ran")
    a = p.parse_args()
    a.zvidpt = str(Path(a.zvidpt).resolve())
    studies = [x.strip() for x in (a.studies or MODES[a.mode]["studies"]).split(",") if x.strip()]
    known = ("cornell-paper", "race", "suite", "cycles")
    unknown = [x for x in studies if x not in known]
    if unknown or not studies:
        p.error(f"--studies: unknown study {', '.join(unknown) or '(none given)'} ({', '.join(known)})")
    s = MODES[a.mode]
    if (a.bitterli or os.environ.get("BITTERLI")) and "suite" not in studies:
        print("(the Bitterli suite is not among the studies: it runs with --full, or with --studies ...,suite)",
              file=sys.stderr)
    out = Path(a.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    log = out / "results.log"
    a.m = machine()
    t0 = time.time()
    sections = {"cornell-paper": None, "race": None, "suite": None, "cycles": None}
    head, checks = [], []
    if "cornell-paper" in studies:
        md, head_paper, c = cornell_paper(a, s, out, log)
        sections["cornell-paper"] = md
        head.append(("`cornell-paper` (indirect light)", *head_paper))
        checks += [(head[-1], *x) for x in c]
    r = race(a, s, out, log) if "race" in studies else None
    if r:
        sections["race"] = r[0]
        head.append(("`cornell-mitsuba` (direct light, glossy, glass)", *r[1]))
        checks += [(head[-1], *x) for x in r[2]]
    plot = None
    r = suite(a, s, out, log) if "suite" in studies else None
    if r:
        # Not a headline row: its heavy tails need the full run's seeds (docs/results.md).
        sections["suite"], plot = r[0], r[2]
        print(f"\nBitterli's complete scenes, geometric mean of path's MSE ÷ zvidpt's: {r[1][2]}")
    r = cycles(a, s, out, log) if "cycles" in studies else None
    if r:
        sections["cycles"] = r[0]
        head.append(("`cornell-paper` against Cycles", *r[1]))
        checks += [(head[-1], *x) for x in r[2]]
    headline = "\n".join(["| scene | measure | `path` | `zvidpt` | peers |", "|---|---|---|---|---|"]
                         + ["| " + " | ".join(row) + " |" for row in head])
    report = [f"# Results ({a.mode})", "", stamp(a.m, a.mode, time.time() - t0), "", "## Headline", "", headline]
    if a.mode == "quick" and checks:
        verdict = check_headline(ROOT / "README.md", checks)
        report += ["", "## Against the README's headline", "", verdict]
        print("\n" + verdict)
    for name, body in sections.items():
        if body:
            report += ["", f"## {name}", "", body]
    (out / "results.md").write_text("\n".join(report) + "\n")
    print("\n" + headline)
    if a.mode == "full" or a.write:
        for name, body in sections.items():
            if body:
                replace_section(ROOT / "docs" / "results.md", name, body)
        if plot and plot.exists():
            shutil.copyfile(plot, ROOT / "docs" / "suite.png")
        if head:
            replace_headline_rows(ROOT / "README.md", head)
        print("rewrote docs/results.md" + (f" and {len(head)} row(s) of the README's headline table" if head else ""))
    print(f"wrote {out / 'results.md'} in {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
