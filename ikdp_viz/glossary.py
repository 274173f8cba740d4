"""The words the viewer uses, each defined once, for a person who has just read about diffusion models.

The panel's "Words" folder lists them; a control's hint that uses a term reads its definition from
here (`define`), so a word means the same in every place it appears. No viser here.
"""

from __future__ import annotations

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
