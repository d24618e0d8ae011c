"""End-to-end demo: a scripted pick/place episode on the UR10 station, recorded to HTML.

    python tools/run_demo.py [--out out/demo.html] [--meshcat]

It builds the station with its depth cameras, perceives the scene, executes three
pick/place actions in full physics on what it perceives (stack a cube on a cube, lay a long
block on a cube, a long block grasped off-centre that tips), follows every object's identity
through perception, prints each outcome and writes one self-contained Meshcat recording.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from drake_symplan.perception.association import associate
from drake_symplan.perception.perceive import Perceiver
from drake_symplan.skills.pick_place import PickPlacePlanner, pick_place
from drake_symplan.structs import Action
from drake_symplan.world.cameras import default_cameras
from drake_symplan.world.scenes import load_scene
from drake_symplan.world.station import Station, StationConfig
from drake_symplan.world.visualization import StartMeshcat, recording

REPO = Path(__file__).resolve().parents[1]
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
    station = Station(StationConfig(cameras=default_cameras()), meshcat=meshcat)
    planner, perceiver = PickPlacePlanner(), Perceiver()
    scene = load_scene(DEMO_SCENE)
    station.reset(scene)
    station.settle(0.3)
    perceived = perceiver.perceive(station)
    # The user's names (from the scene file) -> perceived objects, by the stated positions.
    names = {}
    for spec in scene.objects:
        d = [np.linalg.norm(o.position - spec.position) for o in perceived.objects]
        names[spec.name] = perceived.objects[int(np.argmin(d))].name
    print(f"perceived {len(perceived.objects)} objects: "
          + ", ".join(f"{n}={names[n]}" for n in names))
    with recording(station, out):
        for scripted in SCRIPT:
            action = Action(names[scripted.source], scripted.grasp, names[scripted.target],
                            scripted.release)
            outcome = pick_place(station, planner, action, perceived.object_states())
            print(f"{scripted}: {outcome.status} ({outcome.seconds:.2f} s wall)")
            if outcome.status != "ok":
                return 1
            after = perceiver.perceive(station, prior=perceived)
            track = associate(perceived, after, action)
            names = {user: track[p] for user, p in names.items() if p in track}
            for user, p in names.items():
                o = after.object(p)
                print(f"    {user:3s} {o.type:5s} at ({o.position[0]:.3f}, {o.position[1]:.3f}, "
                      f"{o.position[2]:.3f}) tilt={np.degrees(o.tilt):5.1f} deg")
            perceived = after
    print(f"recording written to {out}")
    if args.meshcat:
        input(f"Meshcat at {meshcat.web_url()}; press Enter to quit")
    return 0


if __name__ == "__main__":
    sys.exit(main())
