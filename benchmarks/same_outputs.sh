#!/usr/bin/env bash
# Are localize's outputs unchanged since BASE?  Runs BASE's code (git archive) and the working tree's on the
# same inputs: `localize --json` on the six real AFAR flights and on one simulated flight (rfsl simulate, seed 7),
# `--method matched` / `--method selfcal` on the first real flight and its text table at 80 columns, and diffs
# the two sets byte for byte (checkout and output folders masked: they differ by construction).
# Needs ../shared; about a minute per side on 2 cores.  Exit 0: identical; 1: the files that differ are listed
# and both sets are kept for a closer look.
# usage: benchmarks/same_outputs.sh BASE [PYTHON]
set -euo pipefail
BASE=${1:?usage: benchmarks/same_outputs.sh BASE [PYTHON]}
PY=${2:-python}
ROOT=$(git rev-parse --show-toplevel)
SHARED=$(cd "$ROOT/../shared" && pwd)
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
mkdir "$TMP/base_src"
git -C "$ROOT" archive "$BASE" | tar -x -C "$TMP/base_src"

outputs() {  # outputs CHECKOUT OUT
  local src=$1 out=$2
  mkdir -p "$out"
  (
    cd "$src"
    export PYTHONPATH=$src COLUMNS=80
    "$PY" -m mission.cli.main import afar-mat "$SHARED/data/afar2023/mat" --out "$out/real" > "$out/import.txt"
    "$PY" -m mission.cli.main simulate missions/spiral.yaml --seed 7 --out "$out/sim" > "$out/simulate.txt"
    for f in "$out"/real/*.csv "$out"/sim/*.csv; do
      "$PY" -m mission.cli.localize "$f" --json > "$out/$(basename "$f" .csv).json"
    done
    first=$(ls "$out"/real/*.csv | head -1)
    for m in matched selfcal; do
      "$PY" -m mission.cli.localize "$first" --method "$m" --json > "$out/method_$m.json"
    done
    "$PY" -m mission.cli.localize "$first" > "$out/table.txt"
  )
  sed -i "s#$src/##g; s#$out/##g" "$out"/*.json "$out"/*.txt
}

outputs "$TMP/base_src" "$TMP/base"
outputs "$ROOT" "$TMP/work"
if diff -rq -x real -x sim "$TMP/base" "$TMP/work"; then
  echo "identical: $(ls "$TMP/work" | wc -l) outputs of $BASE and the working tree"
else
  trap - EXIT
  echo "outputs differ; both sets kept in $TMP (base/, work/)"
  exit 1
fi
