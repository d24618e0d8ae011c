#!/usr/bin/env bash
# Table I: three models x three seeds on one data set, two single-thread runs at a time.
#   bash tools/train_table1.sh [DATA (data_out/hand50k)] [RUNS (runs/<data set name>)]
# Re-running resumes unfinished runs and skips finished ones.
set -u
cd "$(dirname "$0")/.."
data=${1:-data_out/hand50k}
runs=${2:-runs/$(basename "$data")}
run() {
  local out="$runs/$1_s$2" resume=""
  [ -f "$out/metrics.json" ] && return 0
  [ -f "$out/last.pt" ] && resume="--resume"
  .venv/bin/symplan train --model "$1" --data "$data" --out "$out" --seed "$2" \
    --epochs 300 --patience 30 --lr 1e-3 --threads 1 --no-progress --json $resume \
    > "$out.log" 2>&1
}
mkdir -p "$runs"
for seed in 0 1 2; do
  run relational "$seed" & run attentive "$seed" & wait
done
run deepsym 0 & run deepsym 1 & wait
run deepsym 2
.venv/bin/symplan eval effects "$runs"/*_s? --json --plot "$runs/effects.png" > "$runs/eval.json"
echo "Table I: $runs/eval.json"
