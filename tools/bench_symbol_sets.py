"""Benchmark: which of a model's symbols make its symbolic transitions deterministic?

    python tools/bench_symbol_sets.py --run RUN --train DATA --heldout DATA [--margins 3,1]
        [--reference] [--out bench_symbol_sets.json]

Reads the symbols of a trained run on its training data and on a held-out data set, then,
for every subset of its predicates (the others read as constant false) and every read-out
margin, measures `evaluation.operators.determinism`: how often a held-out transition's
symbolic effect is the one most often seen in training after the same action in the same
symbols, the share of situations seen in training at all, and of the training situations
seen twice or more, the share with more than one effect. A selection among candidate
symbol sets (predicators' invention keeps a set only if it pays on the data) would pick
the best row; here it shows what each predicate buys. `--reference` adds the same rows
for hand-made symbols (learning/handmade.py: long(o), on(o, o')), with and without the
contact degrees (without --run: those alone): what symbols of this kind can reach on the data.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import itertools
import json
import platform

from drake_symplan.evaluation.operators import determinism
from drake_symplan.learning.checkpoint import load_run
from drake_symplan.learning.handmade import reference_bits
from drake_symplan.learning.readout import readout_scenes, scenes_symbols
from drake_symplan.shards import fingerprint
from drake_symplan.symbolic.effect_operators import EFFECT

NO_DEGREE = dataclasses.replace(EFFECT, degree=False)


def keep_only(data, unary: tuple[int, ...], relations: tuple[int, ...]):
    """A copy of a SymbolDataset whose other predicates read false and certain."""
    out = copy.copy(data)
    for prefix in ("", "next_"):
        for kind, keep, axis in (("unary", unary, 2), ("relational", relations, 1)):
            bits = getattr(data, f"{prefix}{kind}").copy()
            unsure = getattr(data, f"{prefix}{kind}_uncertain").copy()
            for i in range(bits.shape[axis]):
                if i not in keep:
                    index = (slice(None),) * axis + (i,)
                    bits[index], unsure[index] = 0, False
            setattr(out, f"{prefix}{kind}", bits)
            setattr(out, f"{prefix}{kind}_uncertain", unsure)
    return out


def subsets(n: int):
    return [c for r in range(n + 1) for c in itertools.combinations(range(n), r)]


def symbol_sets(args):
    """(name, margin, semantics, train symbols, held-out symbols) to measure."""
    if args.run:
        model = load_run(args.run)[0]
        for margin in (float(m) for m in args.margins.split(",")):
            yield ("learned", margin, EFFECT, readout_scenes(model, args.train, margin)[0],
                   readout_scenes(model, args.heldout, margin)[0])
    if args.reference:
        train = scenes_symbols(args.train, reference_bits)[0]
        heldout = scenes_symbols(args.heldout, reference_bits)[0]
        for name, semantics in (("reference", EFFECT), ("reference_no_degree", NO_DEGREE)):
            yield name, None, semantics, train, heldout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--run", help="a trained run directory")
    parser.add_argument("--train", required=True, help="its training data set")
    parser.add_argument("--heldout", required=True, help="a held-out data set")
    parser.add_argument("--margins", default="3,1", help="read-out margins (comma-separated)")
    parser.add_argument("--reference", action="store_true",
                        help="also the hand-made reference symbols (learning/handmade.py)")
    parser.add_argument("--out", default="bench_symbol_sets.json")
    args = parser.parse_args()
    if not args.run and not args.reference:
        parser.error("give --run, --reference or both")
    rows = []
    for name, margin, semantics, train, heldout in symbol_sets(args):
        for unary in subsets(train.unary.shape[2]):
            for relations in subsets(train.relational.shape[1]):
                report = determinism(keep_only(train, unary, relations),
                                     keep_only(heldout, unary, relations), semantics)
                report.pop("branching")
                rows.append({"symbols": name, "margin": margin,
                             "unary": [f"p{i}" for i in unary],
                             "relations": [f"r{k}" for k in relations],
                             **{k: round(v, 4) for k, v in report.items()}})
                print(json.dumps(rows[-1]), flush=True)
    out = {"benchmark": "symbol_sets", "run": args.run, "train": args.train,
           "heldout": args.heldout, "train_fingerprint": fingerprint(args.train),
           "heldout_fingerprint": fingerprint(args.heldout),
           "machine": platform.processor() or platform.machine(), "rows": rows}
    with open(args.out, "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
