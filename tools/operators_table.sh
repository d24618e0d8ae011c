#!/usr/bin/env bash
# The operators table (README "Planning at the symbolic level"): models x seeds trained on one
# data set with whole scenes, a bundle per run (effect-first operators; the paper's learner
# too for the baseline rows), each evaluated on one held-out data set (a seed never trained
# on), then summarised.
#   bash tools/operators_table.sh TRAIN_DATA HELDOUT_DATA [RUNS (runs/ops_<train name>)]
# Re-running skips finished steps. Variants: relational (the paper's q.k attention),
# relational_inv (RelationalDeepSym invariant=true), attentive (unary symbols only).
# Environment: SEEDS ("0 1 2"), VARIANTS, MIN_COUNT (effect learner, 10; the paper's
# learner keeps its 50), MAX_PROBLEMS (per k and object count, 30), TRAIN_ONLY (skip the
# bundles and evaluations).
set -u
cd "$(dirname "$0")/.."
data=$1
heldout=$2
runs=${3:-runs/ops_$(basename "$data")}
seeds=${SEEDS:-0 1 2}
variants=${VARIANTS:-relational_inv relational attentive}
one() {  # variant seed
  local v=$1 s=$2 out="$runs/$1_s$2" model=$1 opt=""
  [ "$v" = relational_inv ] && model=relational && opt="--model-option invariant=true"
  if [ ! -f "$out/metrics.json" ]; then
    local resume=""
    [ -f "$out/last.pt" ] && resume="--resume"
    symplan train --config configs/table1.yaml --model "$model" --data "$data" --out "$out" \
      --seed "$s" $opt --no-progress --json $resume > "$out.log" 2>&1 || return 1
  fi
  [ -n "${TRAIN_ONLY:-}" ] && return 0
  for learner in effect paper; do
    [ "$learner" = paper ] && [ "$v" = attentive ] && continue
    local b="$out/bundle_$learner"
    [ -f "$b/operators.json" ] || symplan bundle --run "$out" --data "$data" --out "$b" \
      --learner "$learner" --min-count "$([ $learner = paper ] && echo 50 || echo "${MIN_COUNT:-10}")" \
      > "$b.log" 2>&1 || return 1
    [ -f "$b/eval.json" ] || symplan eval operators --model "$b" --data "$heldout" \
      --max-problems "${MAX_PROBLEMS:-30}" --out "$b/eval.json" > /dev/null 2>> "$b.log"
  done
}
export -f one
export data heldout runs TRAIN_ONLY MIN_COUNT MAX_PROBLEMS
mkdir -p "$runs"
for s in $seeds; do for v in $variants; do echo "$v $s"; done; done \
  | xargs -P 2 -L 1 bash -c 'one "$0" "$1"'
python tools/summarise_operators.py "$runs" --out "$runs/table.json"
