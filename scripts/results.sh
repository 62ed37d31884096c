#!/usr/bin/env bash
# Regenerates the results tables: the README's headline (cornell-paper time to a path
# tracer's error, cornell-mitsuba against Mitsuba 3, Bitterli's complete scenes at equal
# time, cornell-paper against Cycles), each with the machine, threads, commit and date beside it.
#
#   scripts/results.sh --quick [--bitterli COLLECTION] [--out DIR] [--write]
#   scripts/results.sh --full  [--bitterli COLLECTION] [--out DIR]
#   (either with --studies cornell-paper,race,suite,cycles: a subset, e.g. --studies race)
#
# --quick (about 11.5 minutes on 2 cores, plus a 3-minute build) uses shorter references, two
# seeds and a 6-s Bitterli suite, and writes DIR/results.md only, unless --write; --full (about 3 hours) reproduces
# docs/results.md's settings and rewrites its generated sections, docs/suite.png and the
# README's headline table. Without --bitterli (or $BITTERLI) the public-scene suite is
# skipped; without pip's `mitsuba` the race against Mitsuba 3 is, without pip's `bpy` the race
# against Cycles. Details:
# `python3 scripts/results.py --help`.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
exec python3 scripts/results.py --zvidpt target/release/zvidpt "$@"
