"""End-to-end demo: a scripted pick/place episode on the UR10 station, recorded to HTML.

    python tools/run_demo.py [--out out/demo.html] [--meshcat]

It builds the station, executes three pick/place actions in full physics (stack a cube
on a cube, lay a long block across two cubes, a long block grasped off-centre that tips),
prints each outcome and writes one self-contained Meshcat recording of the episode.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from drake_symplan.skills.pick_place import PickPlacePlanner, pick_place  # noqa: E402
from drake_symplan.structs import Action  # noqa: E402
from drake_symplan.world.scenes import load_scene  # noqa: E402
from drake_symplan.world.station import Station  # noqa: E402
from drake_symplan.world.visualization import StartMeshcat, recording  # noqa: E402

DEMO_SCENE = REPO / "tools" / "demo_scene.yaml"
SCRIPT = [
    Action("o1", "center", "o0", "center"),  # cube onto cube
    Action("o2", "center", "o3", "center"),  # long block onto the far cube
    Action("o4", "left", "o1", "center"),  # long block grasped off-centre: tips
]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default=str(REPO / "out" / "demo.html"))
    parser.add_argument("--meshcat", action="store_true",
                        help="keep serving the live Meshcat page until Enter is pressed")
    args = parser.parse_args()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)

    meshcat = StartMeshcat()
    station, planner = Station(meshcat=meshcat), PickPlacePlanner()
    scene = load_scene(DEMO_SCENE)
    station.reset(scene)
    with recording(station, out):
        for action in SCRIPT:
            # Each action starts at time 0 in its own episode state; keep the objects where
            # the last one left them by re-reading the world (perception replaces this later).
            beliefs = station.object_states()
            outcome = pick_place(station, planner, action, beliefs)
            print(f"{action}: {outcome.status} ({outcome.seconds:.2f} s wall)")
            for name, o in outcome.objects.items():
                print(f"    {name:3s} {o.type:5s} end=({o.end[0]:.3f}, {o.end[1]:.3f}, "
                      f"{o.end[2]:.3f}) tilt={o.tilt_deg:5.1f} deg lifted={o.lifted}")
            if outcome.status != "ok":
                return 1
    print(f"recording written to {out}")
    if args.meshcat:
        input(f"Meshcat at {meshcat.web_url()}; press Enter to quit")
    return 0


if __name__ == "__main__":
    sys.exit(main())
