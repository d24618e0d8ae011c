"""`symplan reproduce --scale small|paper [--out DIR] [--ray [ADDRESS]] [--report]`: the whole
pipeline and every results table, resumable (drake_symplan/pipelines/reproduce.py); `--report` writes
the tables of the stages done so far. `symplan curve --scale small|session|paper`: the
learning curve of random against active exploration (drake_symplan/pipelines/learning_curve.py).

Exit status: 0 done, 1 a stage failed (one line on stderr naming it and its log), 2 bad
input."""

from __future__ import annotations

import sys
from pathlib import Path

from drake_symplan.cli.main import CommandError, NegativeAnswer
from drake_symplan.cli.options import (
    add_camera_noise_argument,
    add_device_argument,
    add_json_argument,
    add_solve_arguments,
    check_device,
    check_output_dir,
    positive_int,
    solve_config,
)
from drake_symplan.json_files import read_json


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "reproduce", help="collect, train 3 models x 3 seeds, learn operators, evaluate "
        "effects, operators and planning in the arm; every table into one directory",
        description="Runs every stage of the pipeline as `symplan` commands (recorded in "
        "DIR/provenance.json) and writes DIR/results/results.md with the tables and plots. "
        "Re-running the same command resumes: finished stages are skipped.")
    p.add_argument("--scale", required=True, metavar="NAME",
                   help="a scale of configs/scales.yaml: small, a toy run (~10 min on 2 "
                   "cores); paper, the README's run")
    add_run_arguments(p, "reproduce", "collect and solve the arm problems on Ray",
                      "write results.md from the stages done so far",
                      extra=lambda: (add_solve_arguments(p, monitor_flag=False),
                                     add_camera_noise_argument(p)))
    p.set_defaults(func=run_reproduce)

    c = subparsers.add_parser(
        "curve", help="random against active exploration by data size: coverage, "
        "precision and symbolic planning on one held-out set (and the arm at paper scale)",
        description="Collects a random and an active data set size by size, trains and "
        "evaluates a model at every size (DIR/runs), writes DIR/results/curve.md, .json "
        "and .png. Re-running the same command resumes.")
    c.add_argument("--scale", required=True, metavar="NAME",
                   help="a scale of configs/scales.yaml: small, toy (minutes); session, 5k, "
                   "10k and 25k, 3 seeds at 10k and 25k (about 2 h on 2 cores); paper, "
                   "5k-50k, random to 100k, 3 seeds at 25k/50k, the arm")
    add_run_arguments(c, "curve", "collect and solve on Ray",
                      "write the table from the points done so far")
    c.set_defaults(func=run_curve)


def add_run_arguments(p, name: str, ray_help: str, report_help: str, extra=None) -> None:
    """--out, --jobs, --ray, (extra), --report and --json of a resumable multi-stage run."""
    p.add_argument("--out", type=Path, default=None,
                   help=f"directory (default out/{name}_<scale>)")
    p.add_argument("--jobs", type=positive_int, default=2,
                   help="training runs at a time, and local collection workers (default 2)")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help=f"{ray_help} (no address: this machine)")
    add_device_argument(p, "where the models train (train stages, active rounds)")
    if extra is not None:
        extra()
    p.add_argument("--report", action="store_true", help=f"run nothing: {report_help}")
    add_json_argument(p)


def run_reproduce(args):
    from drake_symplan.pipelines.reproduce import Reproduction, StageFailed
    from drake_symplan.pipelines.scales import load_scale

    load_scale("reproduce", args.scale)  # an unknown name: one line, before any folder
    out = args.out or Path("out") / f"reproduce_{args.scale}"
    check_output_dir(out)
    check_device(args.device)
    rep = Reproduction(args.scale, out, jobs=args.jobs, ray=args.ray, device=args.device,
                       say=lambda text: print(text, file=sys.stderr, flush=True),
                       solve=solve_config(args), camera_noise=args.camera_noise)
    if args.report:
        if not (rep.results / "effects.json").exists():
            raise CommandError(f"nothing to report in {out}: its effects stage has not run")
        path = rep.report()
        return {"status": "report", "results": str(path), "out": str(out)}
    try:
        path = rep.run()
    except StageFailed as e:
        print(f"symplan reproduce: {e}", file=sys.stderr)
        return NegativeAnswer({"status": "failed", "message": str(e), "out": str(out)})
    return {"status": "done", "results": str(path), "out": str(out),
            "provenance": str(out / "provenance.json")}


def run_curve(args):
    from drake_symplan.pipelines.learning_curve import LearningCurve
    from drake_symplan.pipelines.scales import load_scale
    from drake_symplan.pipelines.stages import StageFailed

    load_scale("curve", args.scale)  # an unknown name: one line, before any folder
    out = args.out or Path("out") / f"curve_{args.scale}"
    check_output_dir(out)
    check_device(args.device)
    curve = LearningCurve(args.scale, out, jobs=args.jobs, ray=args.ray, device=args.device,
                          say=lambda text: print(text, file=sys.stderr, flush=True))
    if args.report and not list((out / "runs").glob("*/bundle_effect/eval.json")):
        raise CommandError(f"nothing to report in {out}: no point has been evaluated yet")
    try:
        path = curve.report() if args.report else curve.run()
    except StageFailed as e:
        print(f"symplan curve: {e}", file=sys.stderr)
        return NegativeAnswer({"status": "failed", "message": str(e), "out": str(out)})
    return {"status": "report" if args.report else "done", "results": str(path),
            "out": str(out), "points": read_json(out / "results/curve.json")[
                "points"]}
