"""The demo: the robot solves a goal with the symbols it learned, in full physics.

    python tools/run_demo.py [--model DIR] [--seed N [--objects 3] [--k 2|3]]
                             [--start start.yaml --goal goal.yaml] [--out out/demo.html]
                             [--planner fd] [--timeout 10] [--no-record] [--meshcat] [--json]
                             [--from-scratch --budget-minutes M [--work DIR]]

The same command as `symplan demo` (drake_symplan/cli/demo_cmds.py; the episode in
drake_symplan/pipelines/demo.py, --from-scratch's stages in
drake_symplan/pipelines/from_scratch.py), with the recording and --from-scratch's work
under this repository's out/ and the default problem its models/demo/, wherever it is
run from. `--help` tells every option.

Exit status: 0 success, 1 a verdict that is not success, no plan, or no goal
could be made, 2 bad input (one line on stderr).
"""

from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    from drake_symplan.cli.demo_cmds import main as demo_main

    return demo_main(argv, prog="run_demo.py", out_dir=REPO / "out",
                     problem_dir=REPO / "models" / "demo")


if __name__ == "__main__":
    sys.exit(main())
