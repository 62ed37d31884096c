#!/bin/bash
# Renders every shipped scene with every integrator at deterministic settings into OUT, so
# that two builds can be compared pixel for pixel (a move or rename must change no pixel):
#   scripts/same-images.sh BEFORE_BINARY before/ && scripts/same-images.sh target/release/zvidpt after/
#   for f in before/*.exr; do zvidpt diff "$f" "after/$(basename "$f")"; done   # MSE 0 each
set -euo pipefail
if [ $# -ne 2 ]; then
  echo "usage: scripts/same-images.sh ZVIDPT_BINARY OUT_DIR" >&2
  exit 2
fi
BIN=$(realpath "$1")
OUT=$2
mkdir -p "$OUT"
OUT=$(realpath "$OUT")
cd "$(dirname "$0")/.."
status=0
for dir in scenes/*/; do
  name=$(basename "$dir")
  for integrator in path jensen zvidpt-terminal zvidpt-collision zvidpt "jensen --learned-guide on"; do
    tag=${integrator// /_}
    # shellcheck disable=SC2086 # the integrator's flags split on purpose
    if ! "$BIN" render "$dir" --integrator $integrator --resolution 48x36 --spp 16 --seed 3 --threads 2 \
        -o "$OUT/$name-$tag.exr" --no-png --quiet >/dev/null 2>"$OUT/$name-$tag.log"; then
      echo "failed: $name $integrator: $(tail -1 "$OUT/$name-$tag.log")" >&2
      status=1
    fi
  done
done
exit $status
