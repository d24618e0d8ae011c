#!/usr/bin/env bash
# Table I: three models x three seeds on one data set, single-thread runs, two at a time,
# and the continuous reference (no symbols: the data set's error floor) x three seeds.
#   bash tools/train_table1.sh [DATA (data_out/hand50k_s9)] [RUNS (runs/<data set name>)]
# Re-running resumes unfinished runs and skips finished ones (and ones another invocation
# holds: RUN.lock).
set -u
cd "$(dirname "$0")/.."
data=${1:-data_out/hand50k_s9}
runs=${2:-runs/$(basename "$data")}
run() {  # model seed
  local out="$runs/$1_s$2" resume=""
  [ -f "$out/metrics.json" ] && return 0
  mkdir "$out.lock" 2>/dev/null || return 0
  [ -f "$out/last.pt" ] && resume="--resume"
  symplan train --model "$1" --data "$data" --out "$out" --seed "$2" \
    --epochs 300 --patience 30 --lr 1e-3 --threads 1 --no-progress --json $resume \
    > "$out.log" 2>&1
  rmdir "$out.lock"
}
export -f run
export data runs
mkdir -p "$runs"
# Seed-major, so that an interrupted invocation leaves whole seeds of all four models.
for seed in 0 1 2; do
  for model in relational attentive deepsym reference; do echo "$model $seed"; done
done | xargs -P 2 -L 1 bash -c 'run "$0" "$1"'
symplan eval effects "$runs"/*_s? --json --plot "$runs/effects.png" > "$runs/eval.json"
echo "Table I: $runs/eval.json"
