"""`symplan reproduce --scale small|paper [--out DIR] [--ray [ADDRESS]] [--report]`: the whole
pipeline and every results table, resumable (drake_symplan/reproduce.py); `--report` writes
the tables of the stages done so far.

Exit status: 0 done, 1 a stage failed (one line on stderr naming it and its log), 2 bad
input."""

from __future__ import annotations

import sys
from pathlib import Path

from drake_symplan.cli.main import CommandError, NegativeAnswer, positive_int
from drake_symplan.cli.options import add_json_argument, add_solve_arguments, solve_config


def register(subparsers) -> None:
    from drake_symplan.reproduce import SCALES

    p = subparsers.add_parser(
        "reproduce", help="collect, train 3 models x 3 seeds, learn operators, evaluate "
        "effects, operators and planning in the arm; every table into one directory",
        description="Runs every stage of the pipeline as `symplan` commands (recorded in "
        "DIR/provenance.json) and writes DIR/results/results.md with the tables and plots. "
        "Re-running the same command resumes: finished stages are skipped.")
    p.add_argument("--scale", choices=sorted(SCALES), required=True,
                   help="small: a toy run (~10 min on 2 cores); paper: the README's run")
    p.add_argument("--out", type=Path, default=None,
                   help="directory (default out/reproduce_<scale>)")
    p.add_argument("--jobs", type=positive_int, default=2,
                   help="training runs at a time, and local collection workers (default 2)")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="collect and solve the arm problems on Ray (no address: this machine)")
    add_solve_arguments(p, monitor_flag=False)
    p.add_argument("--report", action="store_true",
                   help="run nothing: write results.md from the stages done so far")
    add_json_argument(p)
    p.set_defaults(func=run_reproduce)


def run_reproduce(args):
    from drake_symplan.reproduce import Reproduction, StageFailed

    out = args.out or Path("out") / f"reproduce_{args.scale}"
    if out.exists() and not out.is_dir():
        raise CommandError(f"--out {out} is a file, not a directory")
    rep = Reproduction(args.scale, out, jobs=args.jobs, ray=args.ray,
                       say=lambda text: print(text, file=sys.stderr, flush=True),
                       solve=solve_config(args))
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
