#!/usr/bin/env bash
# Table I: three models x three seeds on one data set, single-thread runs, two at a time,
# then the continuous reference (no symbols: the data set's error floor) x three seeds.
#   bash tools/train_table1.sh [DATA (data_out/hand50k)] [RUNS (runs/<data set name>)]
# Re-running resumes unfinished runs and skips finished ones (and ones another invocation
# holds: RUN.lock).
set -u
cd "$(dirname "$0")/.."
data=${1:-data_out/hand50k}
runs=${2:-runs/$(basename "$data")}
run() {  # model seed
  local out="$runs/$1_s$2" resume=""
  [ -f "$out/metrics.json" ] && return 0
  mkdir "$out.lock" 2>/dev/null || return 0
  [ -f "$out/last.pt" ] && resume="--resume"
  .venv/bin/symplan train --model "$1" --data "$data" --out "$out" --seed "$2" \
    --epochs 300 --patience 30 --lr 1e-3 --threads 1 --no-progress --json $resume \
    > "$out.log" 2>&1
  rmdir "$out.lock"
}
export -f run
export data runs
mkdir -p "$runs"
printf '%s\n' "relational 0" "attentive 0" "relational 1" "attentive 1" "relational 2" \
  "attentive 2" "deepsym 0" "deepsym 1" "deepsym 2" "reference 0" "reference 1" \
  "reference 2" | xargs -P 2 -L 1 bash -c 'run "$0" "$1"'
.venv/bin/symplan eval effects "$runs"/*_s? --json --plot "$runs/effects.png" > "$runs/eval.json"
echo "Table I: $runs/eval.json"
