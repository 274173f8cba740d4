"""The viewer's words for a person who has just read about diffusion models: the glossary, the Model box, the
joint-space square's texts.

Each term is defined once (`GLOSSARY`); a control's hint that uses a term reads its definition from here
(`define`), so a word means the same in every place it appears. The Model box says "a 4-link arm, denoised in 80
steps, half its poses within 0.007 bone lengths" where it once said "N = 4, film, cossin, p95 (ddpm raw, K=1)",
the technical names kept in brackets. The joint-space square draws two link headings; on an arm of more than two
links its arrows are the denoiser's at poses whose other joints are the highlighted sample's, which it must say,
and on a 2-link arm the target's two solutions are the branches elbow up and elbow down, named where drawn.
No viser here.
"""

from __future__ import annotations

import math

import numpy as np

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
