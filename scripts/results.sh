#!/usr/bin/env bash
# Regenerates the results tables: the README's headline (cornell-paper time to a path
# tracer's error, cornell-mitsuba against Mitsuba 3, cornell-paper against Cycles) and
# Bitterli's complete scenes at equal time, each with the machine, threads, commit and date
# beside it.
#
#   scripts/results.sh --quick [--out DIR] [--write]
#   scripts/results.sh --full  [--bitterli COLLECTION] [--out DIR]
#   (either with --studies cornell-paper,race,suite,cycles: a subset, e.g. --studies race)
#
# --quick runs the headline's studies at the headline's time budgets and seeds with cheaper
# references, writes DIR/results.md (the docs too with --write) and checks every figure
# against the README's headline (ratio and z-score from the seeds' spread). --full (about 3
# hours) reproduces docs/results.md's settings and rewrites its generated sections,
# docs/suite.png and the README's headline table. Without --bitterli (or $BITTERLI) the
# public-scene suite is skipped; without pip's `mitsuba` the race against Mitsuba 3 is,
# without pip's `bpy` the race against Cycles. Details: `python3 scripts/results.py --help`.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
exec python3 scripts/results.py --zvidpt target/release/zvidpt "$@"
