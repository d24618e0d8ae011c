"""What a learned symbol means: each predicate against descriptions computed from the
perceived features and contacts of whole scenes.

A candidate description is a boolean per object (unary: "is a long block", "has an
object on top") or per ordered pair of objects in contact (relations: "x is above y",
"x's centre is over y's footprint"), computed from the feature vector (layout in
features.py: [x, y, z, cos(tilt), long_axis_up, cos(k yaw), sin(k yaw),
is_cube, is_long]) and the perceived contact graph. The literals are the base
candidates and their negations; conjunctions and disjunctions of two literals are
candidates too.

For each predicate, over the reads where the bit is certain (unary: every real object;
relations: ordered pairs perceived in contact, the only pairs the planner reads), the
candidate with the best agreement wins: accuracy, or balanced accuracy when the bit is
rare (set in under 10 % or over 90 % of reads). A single literal beats a combination
of two unless the combination is better by more than a point. The bit's frequency is
reported beside the rate, so that "97 %" on a bit that is almost always 0 reads for what
it is.

No Drake here: `explain_model` reads symbols with learning.readout.readout_scenes.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from drake_symplan.atomic import save_figure
from drake_symplan.learning.checkpoint import load_run, model_from_checkpoint, read_checkpoint
from drake_symplan.learning.readout import readout_scenes
from drake_symplan.shards import load_extra

X, Y, Z, COS_TILT, LONG_UP, COS_KYAW, SIN_KYAW, IS_CUBE, IS_LONG = range(9)
UPRIGHT_COS = float(np.cos(np.radians(10)))  # cos(tilt) above this: resting on a face
HALF_SIDE, HALF_LONG = 0.025, 0.125  # m, boxes.py's half extents
ABOVE = 0.03  # m: x above y when z_x > z_y + ABOVE
LEVEL = 0.01  # m: side by side when |z_x - z_y| < LEVEL
RARE = 0.10  # a bit set in fewer (or more than 1 - RARE) of its reads is rare
SIMPLER_BY = 0.01  # a combination must beat a single literal by this much
MAX_READS = 100_000  # reads scored per predicate at most (a seeded sample beyond)


def _parts(F: np.ndarray) -> dict[str, np.ndarray]:
    """Derived per-object quantities of features [..., 9]."""
    cube, long = F[..., IS_CUBE] > 0.5, F[..., IS_LONG] > 0.5
    upright = F[..., COS_TILT] > UPRIGHT_COS
    up = F[..., LONG_UP]
    half_h = np.where(long, HALF_SIDE + (HALF_LONG - HALF_SIDE) * up, HALF_SIDE)
    k = np.where(long, 2.0, 4.0)
    yaw = np.arctan2(F[..., SIN_KYAW], F[..., COS_KYAW]) / k
    standing = long & (up > 0.9)
    # Footprint half extents along the box's own x and long (y) axis.
    half_y = np.where(long & ~standing, HALF_LONG, HALF_SIDE)
    return {"cube": cube, "long": long, "upright": upright, "up": up, "yaw": yaw,
            "standing": standing, "bottom": F[..., Z] - half_h, "half_y": half_y}


def unary_candidates(F: np.ndarray, contacts: np.ndarray, mask: np.ndarray
                     ) -> list[tuple[str, str, np.ndarray]]:
    """(description, negated description, bool [T, M]) per base candidate for objects of
    scenes F [T, M, 9] with contacts [T, M, M] and real slots mask [T, M]."""
    p = _parts(F)
    c = contacts & mask[:, :, None] & mask[:, None, :]
    dz = F[:, None, :, Z] - F[:, :, None, Z]  # [T, i, j] = z_j - z_i
    lying = p["long"] & p["upright"] & (p["up"] < 0.1)
    c2 = F[..., COS_KYAW]  # cos(2 yaw) for a long block: +1 long axis along world y
    return [
        ("is a cube", "is a long block", p["cube"]),  # the two types
        ("rests on a face (not tilted)", "is tilted", p["upright"]),
        ("is a long block lying flat", "is not a long block lying flat", lying),
        ("is a long block standing on its end", "is not standing on its end", p["standing"]),
        ("is elevated (centre above 4 cm)", "is low (centre below 4 cm)", F[..., Z] > 0.04),
        ("rests on something (bottom above the table)", "rests on the table",
         p["bottom"] > 0.01),
        ("has an object on top", "has nothing on top", (c & (dz > ABOVE)).any(-1)),
        ("lies on another object", "lies on no object", (c & (dz < -ABOVE)).any(-1)),
        ("touches another object", "touches nothing", c.any(-1)),
        ("touches an object beside it", "touches nothing beside it",
         (c & (np.abs(dz) < LEVEL)).any(-1)),
        ("has its long axis along world x", "has no long axis along world x",
         lying & (c2 < -0.5)),
        ("has its long axis along world y", "has no long axis along world y",
         lying & (c2 > 0.5)),
        ("is on the robot's left (y > 0)", "is on the robot's right (y < 0)", F[..., Y] > 0),
        ("is far from the robot (x > 0.75 m)", "is near the robot (x < 0.75 m)",
         F[..., X] > 0.75),
    ]


def _within(px: np.ndarray, fy: np.ndarray, py: dict) -> np.ndarray:
    """Is the xy centre px [..., 2] inside the footprint of boxes fy (features, parts)?"""
    d = px - fy[..., [X, Y]]
    s, co = np.sin(py["yaw"]), np.cos(py["yaw"])
    along = -d[..., 0] * s + d[..., 1] * co  # the long axis is (-sin yaw, cos yaw)
    across = d[..., 0] * co + d[..., 1] * s
    return (np.abs(along) <= py["half_y"]) & (np.abs(across) <= HALF_SIDE)


def relation_candidates(fx: np.ndarray, fy: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
    """(description, negated description, bool [m]) per base candidate for ordered pairs
    (x, y) with features fx, fy [m, 9]."""
    px, py = _parts(fx), _parts(fy)
    dz = fx[:, Z] - fy[:, Z]
    return [
        ("x is above y", "x is not above y", dz > ABOVE),
        ("x is below y", "x is not below y", dz < -ABOVE),
        ("x and y are side by side (level)", "x and y are not level", np.abs(dz) < LEVEL),
        ("x's centre is higher than y's", "x's centre is not higher than y's", dz > 0.005),
        ("x's centre is over y's footprint", "x's centre is off y's footprint",
         _within(fx[:, [X, Y]], fy, py)),
        ("y's centre is over x's footprint", "y's centre is off x's footprint",
         _within(fy[:, [X, Y]], fx, px)),
        ("x and y are the same type", "x and y are of different types",
         px["cube"] == py["cube"]),
        ("x is a cube", "x is a long block", px["cube"]),
        ("y is a cube", "y is a long block", py["cube"]),
        ("x is tilted", "x rests on a face", ~px["upright"]),
        ("y is tilted", "y rests on a face", ~py["upright"]),
        ("x is farther from the robot than y", "x is nearer the robot than y",
         fx[:, X] > fy[:, X]),
        ("x is on y's +y side (larger world y)", "x is on y's -y side (smaller world y)",
         fx[:, Y] > fy[:, Y]),
        ("x is centred on y (within 2 cm in x and y)", "x is off y's centre (2 cm or more)",
         np.linalg.norm(fx[:, [X, Y]] - fy[:, [X, Y]], axis=1) < 0.02),
    ]


def _literals(base):
    """Base candidates and their negations, flattened to [n] bool vectors."""
    out = []
    for pos, neg, v in base:
        v = np.asarray(v, bool).ravel()
        out += [(pos, v), (neg, ~v)]
    return out


def best_description(bits: np.ndarray, base) -> dict:
    """The best-agreeing candidate for `bits` [n] (0/1) among `base`'s literals and their
    pairwise conjunctions and disjunctions (see the module docstring)."""
    b = np.asarray(bits, bool).ravel()
    n = len(b)
    freq = float(b.mean()) if n else 0.0
    out = {"reads": int(n), "frequency": round(freq, 4)}
    if n > MAX_READS:  # scored on a seeded sample: memory stays bounded on large data
        keep = np.sort(np.random.default_rng(0).choice(n, MAX_READS, replace=False))
        b, n = b[keep], MAX_READS
        base = [(pos, neg, np.asarray(v, bool).ravel()[keep]) for pos, neg, v in base]
    if n == 0 or freq in (0.0, 1.0):
        return {**out, "meaning": "never read" if n == 0 else f"constant ({int(freq)})",
                "agreement": None, "metric": None, "accuracy": None,
                "balanced_accuracy": None, "alternatives": []}
    literals = _literals(base)
    names = [t for t, _ in literals]
    vecs = [v for _, v in literals]
    singles = len(vecs)
    for (i, a), (j, c) in itertools.combinations(enumerate(literals), 2):
        if i // 2 != j // 2:  # not a literal with its own negation
            names += [f"{a[0]} and {c[0]}", f"{a[0]}, or {c[0]}"]
            vecs += [a[1] & c[1], a[1] | c[1]]
    C = np.stack(vecs)
    tp, tn = (C & b).sum(1), (~C & ~b).sum(1)
    acc = (tp + tn) / n
    bal = 0.5 * (tp / b.sum() + tn / (~b).sum())
    rare = min(freq, 1 - freq) < RARE
    score = bal if rare else acc
    # Simplicity: a combination of two literals pays SIMPLER_BY.
    ranked = score - np.where(np.arange(len(score)) >= singles, SIMPLER_BY, 0.0)
    order = np.argsort(-ranked, kind="stable")
    seen, top = set(), []
    for i in order:  # distinct descriptions, identical vectors counted once
        key = C[i].tobytes()
        if key not in seen:
            seen.add(key)
            top.append(int(i))
        if len(top) == 4:
            break
    i = top[0]
    return {**out, "meaning": names[i], "agreement": round(float(score[i]), 4),
            "metric": "balanced accuracy" if rare else "accuracy",
            "accuracy": round(float(acc[i]), 4), "balanced_accuracy": round(float(bal[i]), 4),
            "alternatives": [{"meaning": names[k], "agreement": round(float(score[k]), 4)}
                             for k in top[1:]]}


def explain_scenes(features: np.ndarray, mask: np.ndarray, contacts: np.ndarray,
                   unary: np.ndarray, unary_uncertain: np.ndarray, relational: np.ndarray,
                   relational_uncertain: np.ndarray) -> dict:
    """Explanations of every predicate from whole scenes: features [T, M, 9], mask [T, M],
    contacts [T, M, M], unary [T, M, P], relational [T, K, M, M] (and their uncertain
    flags). Returns {"unary": [...], "relations": [...], "scenes", "objects", "pairs"}."""
    mask = np.asarray(mask, bool)
    contacts = np.asarray(contacts, bool)
    ubase = unary_candidates(features, contacts, mask)
    out_u = []
    for j in range(unary.shape[-1]):
        ok = mask & ~np.asarray(unary_uncertain[..., j], bool)
        base = [(p, q, v[ok]) for p, q, v in ubase]
        e = best_description(unary[..., j][ok], base)
        e["uncertain"] = round(float(1 - ok.sum() / max(mask.sum(), 1)), 4)
        out_u.append({"symbol": f"p{j}", "arity": 1, **e})
    m = mask.shape[1]
    pairs = contacts & mask[:, :, None] & mask[:, None, :] & ~np.eye(m, dtype=bool)
    t, i, j = np.nonzero(pairs)
    rbase = relation_candidates(features[t, i], features[t, j])
    out_r = []
    for k in range(relational.shape[1]):
        ok = ~np.asarray(relational_uncertain[t, k, i, j], bool)
        base = [(p, q, v[ok]) for p, q, v in rbase]
        e = best_description(relational[t, k, i, j][ok], base)
        e["uncertain"] = round(float(1 - ok.mean()), 4) if len(ok) else 0.0
        out_r.append({"symbol": f"r{k}", "arity": 2, **e})
    return {"unary": out_u, "relations": out_r, "scenes": int(len(mask)),
            "objects": int(mask.sum()), "pairs_in_contact": int(len(t))}


def explanation_line(e: dict) -> str:
    """'p0: object is a long block lying flat, 97 % (accuracy; bit set in 46 % of ...)'."""
    head = f"{e['symbol']}(x)" if e["arity"] == 1 else f"{e['symbol']}(x, y)"
    meaning = e["meaning"] if e["arity"] == 2 else f"x {e['meaning']}"
    if e["agreement"] is None:
        return f"{head}: {meaning} ({e['reads']} certain reads)"
    return (f"{head}: {meaning}, {e['agreement']:.0%} ({e['metric']}; set in "
            f"{e['frequency']:.0%} of {e['reads']} certain reads, {e['uncertain']:.0%} "
            "uncertain)").replace("%", " %")


def load_scene_arrays(data_dir: str | Path, model, margin: float) -> dict:
    """Whole scenes before and after each transition of a data set, with the model's
    symbols: the keyword arguments of `explain_scenes`."""
    _, s = readout_scenes(model, data_dir, margin=margin)
    feats = [load_extra(data_dir, k) for k in ("scene_state", "scene_next_state")]

    def both(a, b):
        return np.concatenate([a, b])

    return {"features": both(*feats), "mask": both(s.mask, s.mask),
            "contacts": both(s.contacts, s.next_contacts),
            "unary": both(s.unary, s.next_unary),
            "unary_uncertain": both(s.unary_uncertain, s.next_unary_uncertain),
            "relational": both(s.relational, s.next_relational),
            "relational_uncertain": both(s.relational_uncertain, s.next_relational_uncertain)}


def load_model(model_dir: str | Path):
    """The effect model of a bundle directory (model.pt) or a run directory (best.pt)."""
    path = Path(model_dir)
    if (path / "model.pt").is_file():
        return model_from_checkpoint(read_checkpoint(path / "model.pt")).eval()
    return load_run(path)[0]


def explain_model(model_dir: str | Path, data_dir: str | Path, margin: float = 3.0
                  ) -> tuple[dict, dict]:
    """(explanations, the scene arrays they came from) of a model on a data set."""
    arrays = load_scene_arrays(data_dir, load_model(model_dir), margin)
    result = explain_scenes(**arrays)
    result.update({"model": str(model_dir), "data": str(data_dir), "margin": margin})
    return result, arrays


def _side_rect(f: np.ndarray) -> tuple[float, float, float, float]:
    """(x0, z0, width, height) of a box's side view (world x-z), untilted: a sketch."""
    p = _parts(f)
    long_x = float(abs(np.sin(p["yaw"])))  # the long axis's share along world x
    half_x = (HALF_LONG * long_x + HALF_SIDE * (1 - long_x)) if p["long"] and not \
        p["standing"] else HALF_SIDE
    half_z = float(f[Z] - p["bottom"])
    return f[X] - half_x, f[Z] - half_z, 2 * half_x, 2 * half_z


def _draw_scene(ax, f: np.ndarray, mask: np.ndarray, colours: dict[int, str], title: str):
    from matplotlib.patches import Rectangle

    ax.axhline(0, color="0.3", lw=1)
    for i in np.nonzero(mask)[0]:
        x0, z0, w, h = _side_rect(f[i])
        ax.add_patch(Rectangle((x0, z0), w, h, fc=colours.get(int(i), "0.85"), ec="0.2",
                               lw=0.8, alpha=0.9, zorder=3 if int(i) in colours else 2))
    xs = f[mask, X]
    ax.set_xlim(xs.min() - 0.15, xs.max() + 0.15)
    ax.set_ylim(-0.01, 0.30)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=7)


def plot_examples(result: dict, arrays: dict, path: str | Path, examples: int = 3,
                  seed: int = 0) -> Path:
    """One row per predicate: the agreement of its best descriptions, then side views
    (world x-z) of example scenes where the bit is set (red: x; blue: y) and one where
    it is certainly not set."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(seed)
    rows = result["unary"] + result["relations"]
    fig, axes = plt.subplots(len(rows), examples + 2, figsize=(2.4 * (examples + 3),
                             1.9 * len(rows)), squeeze=False,
                             gridspec_kw={"width_ratios": [3] + [1.5] * (examples + 1)})
    mask, feats, contacts = arrays["mask"], arrays["features"], arrays["contacts"]
    for r, e in enumerate(rows):
        ax = axes[r, 0]
        options = [(e["meaning"], e["agreement"])] + [
            (a["meaning"], a["agreement"]) for a in e["alternatives"]]
        options = [(m, a) for m, a in options if a is not None]
        ax.barh(range(len(options)), [a for _, a in options],
                color=["C0"] + ["0.7"] * (len(options) - 1))
        for y, (m, _) in enumerate(options):
            ax.text(0.01, y, m[:70], va="center", fontsize=6)
        ax.set_xlim(0, 1)
        ax.invert_yaxis()
        ax.set_yticks([])
        share = "" if e["agreement"] is None else f", {e['agreement']:.0%} {e['metric']}"
        ax.set_title(f"{e['symbol']}: best descriptions{share}", fontsize=7)
        k = int(e["symbol"][1:])
        if e["arity"] == 1:
            bit, unc = arrays["unary"][..., k], arrays["unary_uncertain"][..., k]
            where = [np.argwhere(mask & ~unc & (bit == v)) for v in (1, 0)]
        else:
            bit = arrays["relational"][:, k]
            unc = arrays["relational_uncertain"][:, k]
            pair = contacts & mask[:, :, None] & mask[:, None, :] & ~np.eye(
                mask.shape[1], dtype=bool)
            where = [np.argwhere(pair & ~unc & (bit == v)) for v in (1, 0)]
        for c in range(examples + 1):
            ax = axes[r, c + 1]
            found = where[0] if c < examples else where[1]
            if not len(found):
                ax.axis("off")
                continue
            hit = found[rng.integers(len(found))]
            t, objects = int(hit[0]), [int(v) for v in hit[1:]]
            colours = dict(zip(objects, ("tab:red", "tab:blue"), strict=False))
            label = ("set" if c < examples else "not set") + f" (scene {t})"
            _draw_scene(ax, feats[t], mask[t], colours, f"{e['symbol']} {label}")
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)
