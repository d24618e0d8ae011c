#!/usr/bin/env bash
# Regenerates the shipped default model, models/learned/, from nothing (about 90 minutes on
# 2 cores): the 50k hand data set with whole scenes (seed 12), one invariant
# RelationalDeepSym (seed 0, Table I settings), its effect-first operators (min count 10).
# The same commands as the relational_s0 stages of `symplan reproduce --scale paper`.
# `--recipe paper` (configs/recipes.yaml): the shipped model's kind of data, the hand alone
# (before its arm twin) with the boxes of before stacks rested (docs/world.md).
# Every step resumes or is skipped when its output is there. Then:
#   symplan eval operators --data data_out/eval2k_s97 --max-problems 30 --json
set -eu
cd "$(dirname "$0")/.."
symplan collect --recipe paper --transitions 50000 --workers 2 --out data_out/hand50k_s12 --seed 12
symplan collect --recipe paper --transitions 2000 --workers 2 --out data_out/eval2k_s97 --seed 97
run=runs/hand50k_s12/relational_s0
resume=""
[ -f "$run/last.pt" ] && resume="--resume"
[ -f "$run/metrics.json" ] || symplan train --model relational --model-option invariant=true \
  --data data_out/hand50k_s12 --out "$run" --seed 0 --epochs 300 --patience 30 --threads 1 \
  --no-progress $resume
symplan bundle --run "$run" --data data_out/hand50k_s12 --out models/learned --learner effect \
  --min-count 10
