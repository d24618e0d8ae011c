"""Where a pick/place sets its source down, read from the skill's own geometry: whether the
source would topple there (`set_down_tips`) and which boxes it would come to touch
(`set_down_meets`). No simulator: the perceived (or predicted) boxes and the skill's rules.
"""

from __future__ import annotations

import numpy as np

from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.stability import unstable
from drake_symplan.actions import Action
from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.features import FEATURE_NAMES

LEANS = 0.06  # m: a source set down with its bottom this low leans on the table if it tips


def _centre(boxes: Boxes, action: Action) -> np.ndarray:
    """Where `action` sets its source's centre down, by its own points."""
    from drake_symplan.skills.geometry import set_down_at  # the skill's geometry

    return set_down_at(action, boxes.object_states())


def set_down(boxes: Boxes, action: Action, centre: np.ndarray | None = None) -> Boxes:
    """`boxes` with `action`'s source where the action sets it down (`centre`, else
    skills/geometry.set_down_at), level in the hand, what rides on it carried along (a
    rider as high as the source's new bottom, left behind, was read as its second support:
    a block released 15 cm off a cube, a block on it, and the tower under it fell)."""
    centre = _centre(boxes, action) if centre is None else centre
    i = boxes.names.index(action.source)
    positions = boxes.positions.copy()
    carried = [i] + [boxes.names.index(n) for n in boxes.riding(action.source)]
    positions[carried] += centre - positions[i]
    down = boxes.moved(positions)
    down.features[i, FEATURE_NAMES.index("cos_tilt")] = 1.0
    down.features[i, FEATURE_NAMES.index("long_axis_up")] = 0.0
    return down


def set_down_tips(boxes: Boxes, action: Action) -> bool:
    """Would `action`'s source topple where the action sets it down (`set_down`;
    stability.unstable), its riders with it, from higher than LEANS (one box on the
    table: a block with its end on a cube leans on the table, as goals have it)? A block
    grasped at its end and released over the centre of a cube atop a tower comes down with
    its centre 7.5 cm off it, and falls; the model, which saw few such steps, may predict
    it resting there. The source is judged as it comes down, level in the hand: one picked
    up leaning (a block with its end on a cube) is set down on a face, and tips where its
    centre is beyond its supports."""
    centre = _centre(boxes, action)  # the refiner's search asks this of every move
    if centre[2] - HALF_EXTENTS[boxes.shapes[boxes.names.index(action.source)][0]][2] <= LEANS:
        return False
    return unstable(set_down(boxes, action, centre), [action.source])


def set_down_meets(boxes: Boxes, action: Action) -> set[str]:
    """The boxes other than its target that `action`'s source, or what rides on it, would
    touch where the action sets it down (`set_down`; boxes.contact_graph). A block set
    centred on a cube reaches 12.5 cm either way and comes to rest on a cube standing
    beside that one too: a contact no plan step over the two boxes predicts."""
    load = {action.source, *boxes.riding(action.source)}
    met = {n for pair in set_down(boxes, action).contacts if len(load & set(pair)) == 1
           for n in pair if n not in load}
    return met - {action.target}
