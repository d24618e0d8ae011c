#!/usr/bin/env bash
# Regenerates the shipped default model, models/learned/, from nothing (about 45 minutes on
# 2 cores): the 31k hand data set with whole scenes, one invariant RelationalDeepSym (seed 0,
# Table I settings), its effect-first operators (min count 10, chosen on data_out/val1k_s98).
# Every step resumes or is skipped when its output is there. Then:
#   symplan eval operators --data data_out/eval2k_s97 --json   (the default model's figures)
set -eu
cd "$(dirname "$0")/.."
symplan collect --backend hand --transitions 31000 --workers 2 --out data_out/hand31k_s12 --seed 12
symplan collect --backend hand --transitions 2000 --workers 2 --out data_out/eval2k_s97 --seed 97
run=runs/ops31k/relational_inv_s0
[ -f "$run/metrics.json" ] || symplan train --config configs/table1.yaml --model relational \
  --model-option invariant=true --data data_out/hand31k_s12 --out "$run" --seed 0 --no-progress
symplan bundle --run "$run" --data data_out/hand31k_s12 --out models/learned --min-count 10
