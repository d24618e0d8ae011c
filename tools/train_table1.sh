#!/usr/bin/env bash
# Table I on the 4k hand data set: three models x three seeds, two runs at a time.
set -u
cd "$(dirname "$0")/.."
run() { .venv/bin/symplan train --model "$1" --data data_out/hand4k --out "runs/hand4k/$1_s$2" \
        --seed "$2" --epochs 300 --patience 30 --lr 1e-3 --threads 1 --no-progress --json \
        > "runs/hand4k/$1_s$2.log" 2>&1; }
mkdir -p runs/hand4k
for seed in 0 1 2; do
  run relational $seed & run attentive $seed & wait
  run deepsym $seed
done
echo done > runs/hand4k/ALL_DONE
