"""The panel's texts (markdown) and the plot's range, from plain values, and the words they use: no viser here.

The words are for a person who has just read about diffusion models: each term is defined once (`GLOSSARY`), and a
control's hint that uses a term reads its definition from here (`define`), so a word means the same in every place it
appears. The Model box says "a 4-link arm, denoised in 80 steps, half its poses within 0.007 bone lengths", the
technical names in brackets. The joint-space square draws two link headings; on an arm of more than two links its
arrows are the denoiser's at poses whose other joints are the highlighted sample's, which it says, and on a 2-link
arm the target's two solutions are the branches elbow up and elbow down, named where drawn.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ikdp_viz.chain_scene import ChainView
from ikdp_viz.planar_scene import SolveView


def target_text(target: np.ndarray, clamped: bool, reach: tuple[float, float]) -> str:
    x, y = target
    text = f"**Target** x = {x:+.3f}, y = {y:+.3f}"
    if clamped:
        inner, outer = reach
        boundary = outer if np.hypot(x, y) >= outer - 1e-9 else inner
        text += f"  \n*Clamped to the workspace boundary* (r = {boundary:.2f}): the arm reaches no farther."
    return text


def sample_note(view, highlight: int, reason: str | None, error_name: str, raw_best: int) -> tuple[str, str]:
    """(" (why this sample, ranked by what)", a line naming the best raw sample or "") for the error line.

    The note sits in parentheses before the numbers, which are the highlighted sample's: with
    refinement, "best" ranks the refined poses, and the sample whose raw pose ranks first is named
    on a line of its own (named before the numbers, it would read as their owner).
    `reason` says why this sample is followed ("the best", "kept by follow mode", "chosen in the panel");
    None: "the best" when it is, else nothing.
    """
    if reason is None:
        reason = "the best" if highlight == view.best_sample() else ""
    best = reason.startswith("the best")
    if best:
        reason += f" by refined {error_name}" if view.refined else f" by {error_name} at t = 0"
    note = f" ({reason})" if reason else ""
    raw_line = ""
    if view.refined and best and raw_best != highlight:
        raw_line = f"by raw {error_name} at t = 0 the best is sample {raw_best + 1}"
    return note, raw_line


FORWARD_NOTE = (  # the readouts' first line while the forward process of teaching.py is on screen
    "**Noise it**: the final poses mixed with one noise ε as training does, x_t = √ᾱ_t · x_0 + √(1 − ᾱ_t) · ε; "
    "t = 0 is the poses themselves, t = T pure noise (no trail: the path goes on to t = T)"
)


def solve_text(
    view: SolveView,
    state: int,
    highlight: int,
    *,
    sampler: str,
    seed: int,
    refine_steps: int,
    solve_seconds: float,
    error: str | None = None,
    reason: str | None = None,
) -> str:
    """The step shown, the highlighted sample's tip error now and at t = 0, the K samples' median, the solve.

    `highlight` is 0-based; the text numbers samples as people count, from 1. `reason`: see `sample_note`.
    """
    last = view.num_states - 1
    note, raw_line = sample_note(view, highlight, reason, "tip error", int(np.argmin(view.tip_error[-1])))
    lines = [
        f"**Step** {state} of {last} (t = {int(view.labels[state])})",
        f"**Tip error**, sample {highlight + 1} of {view.num_samples}{note}: "
        f"{view.tip_error[state, highlight]:.4f} now, {view.tip_error[last, highlight]:.4f} at t = 0",
        f"median of K = {view.num_samples}: {np.median(view.tip_error[state]):.4f} now, "
        f"{np.median(view.tip_error[last]):.4f} at t = 0",
    ]
    if view.refined:
        lines.append(f"refined ({refine_steps} DLS steps): {view.final_tip_error[highlight]:.2e}")
    if raw_line:
        lines.append(raw_line)
    lines.append(f"**Solve** {1000 * solve_seconds:.1f} ms ({sampler}, {last} steps, seed {seed})")
    if error:
        lines.append(f"**Last solve failed** {error}")
    return "  \n".join(lines)


def error_range(tip_error: np.ndarray) -> tuple[int, int]:
    """Whole decades (low, high), as log10 exponents, holding every positive tip error; at least one apart."""
    positive = tip_error[tip_error > 0]
    if not positive.size:
        return -3, -2
    low = int(np.floor(np.log10(max(float(positive.min()), 1e-6))))
    high = int(np.ceil(np.log10(float(positive.max()))))
    return low, max(high, low + 1)


# The 3-D viewer's panel texts, in millimetres and degrees, from plain values: no viser here.
def pose_text(target: np.ndarray, label: str = "Target") -> str:
    """The target: position in mm, then (a pose target) its rotation as the quaternion (w, x, y, z)."""
    x, y, z = 1000 * np.asarray(target[:3])
    text = f"**{label}** x = {x:+.1f}, y = {y:+.1f}, z = {z:+.1f} mm"
    if len(target) < 7:
        return text
    w, qx, qy, qz = target[3:7]
    return text + f"  \nwxyz = ({w:.3f}, {qx:+.3f}, {qy:+.3f}, {qz:+.3f})"


def error_pair(position_m: float, rotation_rad: float, measure: str = "rotation") -> str:
    """A hand error in mm and degrees; `measure` (ChainView.rotation_measure) says what the degrees are: the
    rotation, a free axis's angle ("z axis"), or nothing ("none": position only)."""
    position = f"{1000 * position_m:.1f} mm"
    if measure == "none":
        return position
    angle = f"{np.degrees(rotation_rad):.2f}°"
    return f"{position} / {angle}" if measure == "rotation" else f"{position} / {angle} ({measure})"


def target_kind_text(measure: str) -> str | None:
    """A line saying what a partial target asks for (ChainView.rotation_measure); None for a full pose."""
    if measure == "rotation":
        return None
    if measure == "none":
        return "**Position only**: any hand rotation counts; the errors are the hand's distance alone"
    return f"**The hand's {measure} free**: any turn about it counts; the angle is that axis's miss"


def chain_solve_text(
    view: ChainView,
    state: int,
    highlight: int,
    *,
    sampler: str,
    seed: int,
    refine_steps: int,
    solve_seconds: float,
    reason: str | None = None,
) -> str:
    """The step shown; the highlighted sample's hand error now and at t = 0; the K samples' median; the solve.

    Samples are ranked by ChainView.best_sample (position + 0.1 m per radian); `reason`: readouts.sample_note.
    """
    last = view.num_states - 1
    raw_best = int(np.argmin(view.position_error[-1] + 0.1 * view.rotation_error[-1]))
    note, raw_line = sample_note(view, highlight, reason, "hand error", raw_best)
    measure = view.rotation_measure
    if view.num_effectors > 1:  # one line per hand, named by its link; the median is of the worst hand's errors
        (now_position, now_rotation), (end_position, end_rotation) = view.hand_errors(state), view.hand_errors(last)
        lines = [
            f"**Step** {state} of {last} (t = {int(view.labels[state])})",
            f"**Hand errors**, sample {highlight + 1} of {view.num_samples}{note}:",
            *(f"{name}: {error_pair(now_position[highlight, e], now_rotation[highlight, e], measure)} now, "
              f"{error_pair(end_position[highlight, e], end_rotation[highlight, e], measure)} at t = 0"
              for e, name in enumerate(view.effector_names)),
            f"median of K = {view.num_samples} at t = 0, worst hand: "
            f"{error_pair(np.median(view.position_error[last]), np.median(view.rotation_error[last]), measure)}",
        ]  # fmt: skip
    else:
        position, rotation = view.position_error[:, highlight], view.rotation_error[:, highlight]
        lines = [
            f"**Step** {state} of {last} (t = {int(view.labels[state])})",
            f"**Hand error**, sample {highlight + 1} of {view.num_samples}{note}: "
            f"{error_pair(position[state], rotation[state], measure)} now, "
            f"{error_pair(position[last], rotation[last], measure)} at t = 0",
            f"median of K = {view.num_samples} at t = 0: "
            f"{error_pair(np.median(view.position_error[last]), np.median(view.rotation_error[last]), measure)}",
        ]
    if view.refined:
        position, rotation = view.hand_errors()
        pairs = [error_pair(position[highlight, e], rotation[highlight, e], measure) for e in range(view.num_effectors)]
        if view.num_effectors > 1:
            pairs = [f"{name} {pair}" for name, pair in zip(view.effector_names, pairs, strict=True)]
        lines.append(f"refined ({refine_steps} DLS steps): " + ", ".join(pairs))
    if raw_line:
        lines.append(raw_line)
    kind = target_kind_text(measure)
    if kind is not None:
        lines.insert(1, kind)
    lines.append(f"**Solve** {1000 * solve_seconds:.1f} ms ({sampler}, {last} steps, seed {seed})")
    return "  \n".join(lines)


def miss_text(view: ChainView, arm, *, beyond_reach) -> str | None:
    """What the panel says when the best returned pose (refined when refinement is on) misses the target by more
    than the arm's tolerance (1 mm, 1°); None when it reaches. Several end effectors: it reaches when every hand is
    within the tolerance; the hands that miss are named, each hand beyond reach said to be (`beyond_reach`: one
    bool per end effector, or one for all).

    It says "out of reach" only where the target lies beyond the reach: its position as asked lay outside the
    reach ball, which bounds every pose the arm reaches, so the point solved (moved onto the ball) is the nearest
    there can be, and the best pose's miss of it is the nearest reached pose's. Inside the ball the model's miss
    proves nothing of the reach, so the miss is said plainly, with no cause.
    """
    best = view.best_sample()
    measure = view.rotation_measure
    if view.num_effectors > 1:
        return hands_miss_text(view, arm, best, np.broadcast_to(beyond_reach, (view.num_effectors,)))
    beyond_reach = bool(np.all(beyond_reach))
    position, rotation = view.final_position_error[best], view.final_rotation_error[best]
    if position <= arm.position_tolerance and (measure == "none" or rotation <= arm.rotation_tolerance):
        return None
    pair = error_pair(position, rotation, measure)
    if beyond_reach:
        return (f"**Out of reach**: the target lies beyond the arm's reach; the nearest pose reached (sample "
                f"{best + 1}) misses it by {pair}")  # fmt: skip
    tolerance = f"{1000 * arm.position_tolerance:g} mm"
    tolerance += "" if measure == "none" else f" / {np.degrees(arm.rotation_tolerance):g}°"
    return f"**No sample reaches the target**: the best (sample {best + 1}) misses it by {pair}, beyond {tolerance}"


def hands_miss_text(view: ChainView, arm, best: int, beyond_reach: np.ndarray) -> str | None:
    """miss_text of several end effectors: the best sample's hands beyond the tolerances, each by its link's name."""
    measure = view.rotation_measure
    position, rotation = (errors[best] for errors in view.hand_errors())  # (E,) each
    missed = (position > arm.position_tolerance) | ((measure != "none") & (rotation > arm.rotation_tolerance))
    if not missed.any():
        return None
    far = [name for name, miss, out in zip(view.effector_names, missed, beyond_reach, strict=True) if miss and out]
    misses = ", ".join(f"{name} by {error_pair(position[e], rotation[e], measure)}"
                       for e, name in enumerate(view.effector_names) if missed[e])  # fmt: skip
    if far:
        return (f"**Out of reach**: the target of {', '.join(far)} lies beyond its arm's reach; the nearest pose "
                f"reached (sample {best + 1}) misses {misses}")  # fmt: skip
    tolerance = f"{1000 * arm.position_tolerance:g} mm"
    tolerance += "" if measure == "none" else f" / {np.degrees(arm.rotation_tolerance):g}°"
    return (f"**No sample reaches the targets** (every hand within {tolerance}): the best (sample {best + 1}) "
            f"misses {misses}")  # fmt: skip


def chain_model_text(arm, num_timesteps: int, metadata: dict, *, effectors=None, chains=None) -> str:
    """A chain checkpoint's robot, schedule, denoiser and the accuracy measured when it was saved. `effectors`:
    the end effectors' link names (None: the chain's one); `chains`: the chains whose URDF gives the meshes (None:
    the arm itself)."""
    model, metrics = metadata.get("model", {}), metadata.get("metrics", {})
    hands = arm.ee_link if effectors is None else " + ".join(effectors)
    lines = [
        f"**Robot** {arm.base_link} → {hands}, {arm.num_joints} joints, {arm.target} targets, **T** = {num_timesteps}",
        f"**denoiser** {model.get('denoiser', {}).get('kind', '?')}, representation {model.get('representation', '?')}",
    ]
    if metrics:
        lines.append(saved_metrics_text(metrics))
    missing = [chain for chain in ([arm] if chains is None else chains)
               if chain.recorded_urdf_path is not None and chain.chain_description() is None]  # fmt: skip
    if missing:
        # the shipped robots' meshes come from example-robot-data (the [robots] extra, 400 MB): say why none show;
        # by the file's name only, as the recorded path is the training machine's
        name = Path(missing[0].recorded_urdf_path).name
        lines.append(f"**No meshes**: no {name} here (`pip install example-robot-data`); skeletons only")
    return "  \n".join(lines)


def saved_metrics_text(metrics: dict) -> str:
    """The accuracy a chain checkpoint measured when it was saved, in words with units (mm, degrees), not raw keys."""
    numbers = {key: float(value) for key, value in metrics.items() if isinstance(value, (int, float))}
    statistics = (("median", "median"), ("mean", "mean"), ("95th percentile", "p95"))
    position = [f"{name} {1000 * numbers[f'tip_error_{key}']:.1f} mm" for name, key in statistics
                if f"tip_error_{key}" in numbers]  # fmt: skip
    rotation = [f"{name} {math.degrees(numbers[f'rotation_error_{key}']):.1f}°" for name, key in statistics
                if f"rotation_error_{key}" in numbers]  # fmt: skip
    parts = []
    if position:
        parts.append("hand position error " + ", ".join(position))
    if rotation:
        parts.append("rotation error " + ", ".join(rotation))
    if "limit_violations" in numbers:
        parts.append(f"{numbers['limit_violations']:g} joint-limit violations")
    how = []
    if "step" in numbers:
        how.append(f"{numbers['step']:,.0f} training steps")
    if "eval_targets" in numbers:
        how.append(f"{numbers['eval_targets']:g} targets")
    if isinstance(metrics.get("sampler"), str):
        how.append(metrics["sampler"])
    return "**at save**" + (f" ({', '.join(how)})" if how else "") + ": " + "; ".join(parts)


# term -> one sentence; in the order a learner meets them on the page
GLOSSARY: dict[str, str] = {
    "pose": "the arm's joint angles; the model's job is to find poses whose tip lands on the red ✕ (the target)",
    "t, T": "diffusion time: t = T is pure noise (random joint angles), t = 0 the finished pose",
    "x_t": "the pose at diffusion time t, part pose and part noise; x_T is the pure noise a run starts from",
    "x̂0": "the denoiser's guess of the finished pose x_0, from x_t: x_t minus the noise it predicts, rescaled",
    "denoiser": "the network: given x_t, t and the target, it predicts the noise in x_t",
    "ᾱ_t": "how much of the pose is left at time t: x_t = √ᾱ_t · pose + √(1 − ᾱ_t) · noise, 1 at t = 0, near 0 at T",
    "σ": "the noise level √(1 − ᾱ_t): 0 for the clean pose, near 1 for pure noise",
    "forward process": "training's direction: a clean pose mixed with more and more noise as t grows (noise it)",
    "reverse process": "sampling's direction: pure noise denoised step by step to a pose, t = T → 0",
    "K samples": "K runs at once from K different noises: one target has many poses that reach it",
    "tip error": "distance from the arm's tip to the target, in bone lengths (a robot: mm at the hand)",
    "prior": "the poses the model was trained on, before any target: random joint angles, p(pose)",
    "p(pose | target)": "what the model samples: poses given a target, all the ways to reach it",
    "DDPM": "the paper's sampler: every one of the T steps adds fresh noise (stochastic)",
    "stochastic": "random at every step: from the same x_T, a new run lands somewhere else",
    "deterministic": "no randomness after x_T: from the same x_T, every run lands on the same pose",
    "ODE": "ordinary differential equation: the smooth, noise-free path DDIM follows from x_T to a pose",
    "DDIM": "a deterministic sampler on the same network: it follows the ODE in a few big steps (e.g. 20)",
    "DPM-Solver++": "a deterministic sampler like DDIM, a higher-order step for even fewer network calls",
    "student": "a copy of the network trained (distilled) to land in 2 to 4 steps where its teacher lands",
    "teacher": "the model a student was distilled from, sampled with all its steps",
    "DLS": "damped least squares: a few classic IK steps that polish a sampled pose onto the target",
    "elbow up, elbow down": "the two poses of a 2-link arm that reach one target, the elbow bent one way or the other",
    "heading": "a link's angle to the +x axis (the model's own coordinates), not the angle between two links",
    "p95": "95th percentile: 95 of 100 targets were solved at least this well",
    "FiLM": "the way the denoiser reads t and the target: they scale and shift its hidden features",
    "cossin": "each angle given to the network as (cos, sin), so -180° and 180° are one value",
}


def define(term: str) -> str:
    """ "term: definition" for a hint; a ValueError names the term when the glossary lacks it."""
    if term not in GLOSSARY:
        raise ValueError(f"term: expected one of the glossary's {len(GLOSSARY)} terms, got {term!r}")
    return f"{term}: {GLOSSARY[term]}"


def glossary_markdown() -> str:
    """The Words folder's text, one line per term."""
    return "  \n".join(f"**{term}** {definition}" for term, definition in GLOSSARY.items())


REPRESENTATION_WORDS = {
    "cossin": "each angle as (cos, sin), so -180° and 180° are one value",
    "angle": "each angle divided by π, as the paper does",
}
DENOISER_WORDS = {
    "film": "a small MLP that reads t and the target through FiLM",
    "paper": "the paper's transformer",
    "mlp": "a plain MLP",
}
SAMPLER_WORDS = {"ddpm raw, K=1": "DDPM, one sample per target, no polish"}


def model_words(num_links: int, lengths, num_timesteps: int, metadata: dict, student_steps: int | None = None) -> str:
    """The planar Model box: `student_steps` the folded-in student's steps (None: the model has no student)."""
    model, metrics = metadata.get("model", {}), metadata.get("metrics", {})
    shown_lengths = ", ".join(f"{length:g}" for length in lengths)
    lines = [
        f"**A {num_links}-link planar arm** (N = {num_links}), bones {shown_lengths} long; it reaches up to "
        f"{sum(lengths):g} from its base.",
        f"**Denoising**: T = {num_timesteps} steps from pure noise to a pose "
        f"({model.get('schedule', {}).get('kind', '?')} noise schedule).",
    ]
    representation, denoiser = model.get("representation", "?"), model.get("denoiser", {}).get("kind", "?")
    lines.append(
        f"**The network**: {DENOISER_WORDS.get(denoiser, denoiser)} ({denoiser}); it sees "
        f"{REPRESENTATION_WORDS.get(representation, representation)} ({representation})."
    )
    if "tip_error_median" in metrics:
        sampler = str(metrics.get("sampler", ""))
        how = SAMPLER_WORDS.get(sampler, sampler)
        lines.append(
            f"**How well it learned** ({metrics.get('step', '?')} training steps): on "
            f"{metrics.get('eval_targets', 'its')} random targets, half the tips land within "
            f"{metrics['tip_error_median']:.4f} bone lengths of the target, 95 in 100 within "
            f"{metrics.get('tip_error_p95', float('nan')):.4f} (p95; {how})."
        )
    if student_steps is not None:
        lines.append(
            f"**Its student**: a copy distilled to land in {student_steps} steps where the full DDPM lands: "
            "the sampler “student”."
        )
    return "  \n".join(lines)


JOINT_SPACE_HINT = (
    "Beside the arm, a square of two link angles (each link's heading to the +x axis; −π and π meet at the edges). "
    "Dots: the K samples at the step shown. Purple arrows: for a grid of poses taken as x_t, where the network's "
    "guess x̂0 lies (x_t → x̂0). On a 2-link arm the red ✕ are the target's two exact solutions, elbow up and elbow "
    "down; on more links the solutions form a continuum, so dark ✕ mark the final samples instead, and the other "
    "links are held at the highlighted sample's angles."
)


def joint_space_title(first: str, second: str) -> str:
    """The square's title: which angles, and what the arrows are."""
    return f"Joint space: link angles {first} (→) and {second} (↑); arrows: x_t → the network's guess x̂0"


def held_text(names: tuple[str, ...], joints: tuple[int, int], headings) -> str:
    """The line under the title on an arm of more than two links: the other joints' values, in degrees.

    `names` every joint's label (θ1 .. θN), `joints` the pair shown, `headings` (N,) the highlighted sample's.
    """
    headings = np.asarray(headings, dtype=np.float64)
    if len(names) != len(headings):
        raise ValueError(f"headings: expected {len(names)} angles, one per joint, got {len(headings)}")
    others = [index for index in range(len(names)) if index not in joints]
    if not others:
        return ""
    values = ", ".join(f"{names[index]} = {math.degrees(float(headings[index])):.0f}°" for index in others)
    return f"arrows with {values} (the blue sample's, at the step shown)"


def branch_name(lengths, headings) -> str:
    """A 2-link pose's branch: "elbow up" when its elbow lies left of the line from the base to its tip (for a
    target ahead, above it), "elbow down" when right. `headings` (2,) absolute, as the solution set gives them."""
    first, second = (float(value) for value in headings)
    l1, l2 = (float(length) for length in lengths)
    elbow = np.array([l1 * math.cos(first), l1 * math.sin(first)])
    tip = elbow + np.array([l2 * math.cos(second), l2 * math.sin(second)])
    side = tip[0] * elbow[1] - tip[1] * elbow[0]  # z of tip × elbow: positive when the elbow is counterclockwise
    return "elbow up" if side > 0 else "elbow down"
