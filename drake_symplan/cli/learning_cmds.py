"""`symplan train`, `symplan eval effects`, `symplan symbols`: the learning commands.

torch is imported inside the command functions, so that building the parser (which
loads every command module) stays cheap.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from drake_symplan.cli.main import CommandError
from drake_symplan.cli.options import (
    MODELS,
    add_device_argument,
    add_json_argument,
    check_output_dir,
    check_output_file,
    nonnegative_float,
    positive_float,
    positive_int,
    seed,
)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "train", help="train an effect model on a data set",
        description="Trains an effect model on a data set into a run directory. A setting "
        "not given as a flag comes from the --config file, else from TrainConfig's defaults, "
        "which are Table I's settings (configs/table1.yaml; learning/trainer.py).")
    p.add_argument("--config", type=Path, metavar="FILE",
                   help="YAML file of TrainConfig settings, e.g. configs/table1.yaml; "
                   "flags given on the command line override it")
    p.add_argument("--model", choices=MODELS, metavar="MODEL",
                   help="one of %(choices)s; required, here or in --config; reference: no "
                   "symbols, the data set's error floor (models.py)")
    p.add_argument("--data", help="data set directory (shards + manifest.json); required, "
                   "here or in --config")
    p.add_argument("--out", help="run directory to create (or resume); required, here or "
                   "in --config")
    p.add_argument("--epochs", type=positive_int, help="at most this many epochs")
    p.add_argument("--batch-size", type=positive_int, help="transitions per Adam step")
    p.add_argument("--lr", type=positive_float, help="Adam learning rate")
    p.add_argument("--seed", type=seed, help="model initialisation, shuffling and the split")
    p.add_argument("--patience", type=positive_int,
                   help="stop after this many epochs without a better validation loss")
    p.add_argument("--threads", type=positive_int, help="torch.set_num_threads")
    add_device_argument(p, "where it trains", default=None)  # None: --config's, else auto
    p.add_argument("--temperature", type=positive_float,
                   help="Gumbel-sigmoid temperature (see learning/gumbel.py)")
    p.add_argument("--soft", dest="hard", action="store_const", const=False,
                   help="soft Gumbel-sigmoid samples (default: straight-through hard bits)")
    p.add_argument("--model-option", action="append", default=[], metavar="KEY=VALUE",
                   help="a constructor argument of the model, e.g. n_unary=4 or key_dim=32 "
                   "(repeatable; see learning/models.py); added to --config's model_kwargs")
    p.add_argument("--init", type=Path, metavar="RUN",
                   help="start from the weights of this run's best checkpoint (a run "
                   "directory or a .pt file), e.g. an effect-only run fine-tuned with "
                   "--model-option transition_weight=0.003 (learning/transition.py)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    p.add_argument("--no-progress", dest="progress", action="store_const", const=False,
                   help="no progress bar")
    add_json_argument(p)
    p.set_defaults(func=cmd_train)

    p = eval_subparsers(subparsers).add_parser(
        "effects", help="test-set effect error (cm) of runs per model: overall and by "
        "object count, role and outcome")
    p.add_argument("runs", nargs="+", help="run directories")
    p.add_argument("--data", default=None,
                   help="data set directory if it moved (must have the run's fingerprint)")
    p.add_argument("--plot", default=None, help="write a bar chart to this PNG")
    add_json_argument(p)
    p.set_defaults(func=cmd_eval_effects)

    p = subparsers.add_parser("symbols", help="read unary and relational symbols of a data set")
    p.add_argument("run", help="run directory")
    p.add_argument("--data", required=True, help="data set directory")
    p.add_argument("--out", required=True, help="output .npz file")
    p.add_argument("--margin", type=nonnegative_float, default=None,
                   help="a bit is uncertain when |logit| < margin (default 3.0)")
    add_json_argument(p)
    p.set_defaults(func=cmd_symbols)


def eval_subparsers(subparsers):
    """The sub-commands of `symplan eval`, creating `eval` on first use.

    Other command modules add their evaluations (e.g. `eval planning`) with
    `learning_cmds.eval_subparsers(subparsers).add_parser(...)`, in any order.
    """
    parser = subparsers.choices.get("eval")
    if parser is None:
        parser = subparsers.add_parser("eval", help="evaluate trained runs and plans")
        parser.set_defaults(eval_subparsers=parser.add_subparsers(dest="eval_command",
                                                                  required=True))
    return parser.get_default("eval_subparsers")


# The flags of `symplan train` that set the TrainConfig field of the same name.
TRAIN_FLAGS = ("model", "data", "out", "epochs", "batch_size", "lr", "seed", "patience",
               "threads", "temperature", "hard", "progress", "device")


def train_config(args: argparse.Namespace):
    """The TrainConfig of `symplan train`: TrainConfig's defaults, overridden by the
    --config file's settings, overridden by the flags given."""
    from drake_symplan.learning.trainer import TrainConfig
    from drake_symplan.typed_yaml import read_fields

    values = read_fields(args.config, TrainConfig) if args.config is not None else {}
    values.update({k: getattr(args, k) for k in TRAIN_FLAGS if getattr(args, k) is not None})
    if args.model_option:
        values["model_kwargs"] = {**values.get("model_kwargs", {}),
                                  **parse_model_options(args.model_option)}
    if args.init is not None:
        init = args.init / "best.pt" if args.init.is_dir() else args.init
        if not init.is_file():
            raise CommandError(f"--init {args.init}: no checkpoint there (missing checkpoint)")
        values["init"] = str(init)
    missing = [f"--{k}" for k in ("model", "data", "out") if k not in values]
    if missing:
        raise CommandError(f"give {', '.join(missing)}, as flags or in the --config file")
    return TrainConfig(**values)


def cmd_train(args: argparse.Namespace) -> dict:
    from drake_symplan.learning.trainer import train

    config = train_config(args)
    check_output_dir(config.out)
    return train(config, resume=args.resume)


def parse_model_options(items: list[str]) -> dict:
    """{"n_unary": 4} from ["n_unary=4"]; values are YAML scalars (int, float, bool, str)."""
    import yaml

    options = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise ValueError(f"model option {item!r} is not KEY=VALUE")
        options[key.strip()] = yaml.safe_load(value)
    return options


def cmd_eval_effects(args: argparse.Namespace) -> dict:
    from drake_symplan.datasets import OUTCOMES
    from drake_symplan.evaluation.effects import evaluate_runs, format_summary, plot_errors

    check_output_file(args.plot, "--plot")
    result = evaluate_runs(args.runs, args.data, OUTCOMES)
    if args.plot:
        result["plot"] = str(plot_errors(result["models"], args.plot))
    if not args.json:
        print("\n".join(format_summary(result["models"])))
    return result


def cmd_symbols(args: argparse.Namespace) -> dict:
    from drake_symplan.learning.gumbel import DEFAULT_MARGIN
    from drake_symplan.learning.readout import readout_dataset, uncertainty_counts

    check_output_file(args.out, "--out")
    margin = DEFAULT_MARGIN if args.margin is None else args.margin
    symbols = readout_dataset(args.run, args.data, margin=margin)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    symbols.save(out)
    t, k = len(symbols), symbols.n_relations
    result = {"out": str(out), "transitions": t, "objects": symbols.n_objects,
              "unary_dim": symbols.n_unary, "relations": k, "margin": margin,
              **uncertainty_counts(symbols)}
    if not args.json:
        print(f"wrote {out}: {t} transitions, {result['unary_dim']} unary bits, {k} relations")
    return result
