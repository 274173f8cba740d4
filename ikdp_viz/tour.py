"""The guided first visit: six short steps, each one sentence and a preset view of the panel's settings.

Each step is data: what it says and the settings it puts on screen (`TourView`). The app applies a view
as a user would, through the panel's controls, so what the tour shows is what those controls show, and
leaving the tour returns to the viewer's default view. No viser here.
"""

from __future__ import annotations

from dataclasses import dataclass

TWO_LINK_MODEL = "ikdp_n2"  # the model whose target has exactly two answers, elbow up and elbow down
TWO_LINK_TARGET = (1.2, 0.8)  # a target of that arm where both branches are clear apart


@dataclass(frozen=True)
class TourView:
    """The panel's settings a step shows; None keeps the viewer's default for that setting."""

    model: str | None = None  # a shipped model's name; None: the model the viewer opened
    target: tuple[float, float] | None = None  # None: the target the viewer had when the tour began
    samples: int = 16  # K
    show_trail: bool = True
    show_estimate: bool = False  # x̂0 in purple
    timestep: int | None = None  # the step shown; None: play the denoising from t = T and stop at t = 0
    sampler: str = "ddpm"
    compare: str = "off"  # a second sampler from the same x_T, drawn beside
    joint_space: bool = False
    schedule: bool = False  # open the schedule folder (the noise schedule plot)


@dataclass(frozen=True)
class TourStep:
    title: str
    sentence: str  # one sentence: what the view shows and why
    view: TourView
    look_for: str  # what the page must draw for the sentence to be true (a browser test reads this)


TOUR: tuple[TourStep, ...] = (
    TourStep(
        "Noise becomes a pose",
        "Each of the 16 arms (the blue one is followed) starts as random joint angles, pure noise at t = T; step by "
        "step the network removes noise, and at t = 0 every arm's tip reaches the red ✕, the target.",
        TourView(show_trail=False),
        "the final samples' tips at the target",
    ),
    TourStep(
        "x̂0, the network's guess",
        "At t = 50 the blue arm is still mostly noise, but x̂0 (purple), the pose the network guesses from the noise "
        "it predicts, already reaches toward ✕; each step moves the arm only part of the way to x̂0 and keeps some "
        "noise, because an early guess is a blur of many answers that later steps sharpen.",
        TourView(show_trail=False, show_estimate=True, timestep=50),
        "the estimate nearer the target than the state",
    ),
    TourStep(
        "The error chart",
        "The chart under Readouts (scroll the panel down) plots the blue arm's tip error against t (log scale, "
        "in bone lengths): it stays "
        "near 1 while noise dominates and falls in the last steps, where the pose forms; a small error at a large t "
        "is luck, not progress, since that state is still mostly noise.",
        TourView(timestep=0),
        "the highlighted error at t = 0 far below its error at t = T",
    ),
    TourStep(
        "One target, many answers",
        "64 samples from 64 different noises all reach the same ✕ with different poses: the model learned "
        "p(pose | target), every way to reach the target, not one answer.",
        TourView(samples=64, show_trail=False, timestep=0),
        "64 distinct final poses, all at the target",
    ),
    TourStep(
        "Two branches: elbow up, elbow down",
        "A 2-link arm reaches a target in exactly two ways, elbow up and elbow down: the two red ✕ in the joint-space "
        "square (the two links' angles) are those poses, and the samples split between them.",
        TourView(model=TWO_LINK_MODEL, target=TWO_LINK_TARGET, timestep=0, joint_space=True),
        "samples on both branches",
    ),
    TourStep(
        "Samplers: stochastic and deterministic",
        "DDPM adds fresh noise at each of its T steps; DDIM, drawn beside from the same x_T, follows a noise-free "
        "path in 20 steps (the schedule plot marks where each stops), so “again from the same x_T” lands DDPM "
        "somewhere new each time and DDIM on the same poses.",
        TourView(timestep=0, compare="ddim", schedule=True),
        "the compared sampler drawn beside",
    ),
)


def tour_markdown(index: int) -> str:
    """The Tour folder's text for step `index` (0-based): its number, title and sentence."""
    if not 0 <= index < len(TOUR):
        raise ValueError(f"index: expected a tour step 0 .. {len(TOUR) - 1}, got {index}")
    step = TOUR[index]
    return f"**{index + 1} of {len(TOUR)} · {step.title}**  \n{step.sentence}"


DEFAULT_VIEW = TourView()  # what leaving the tour returns to: the viewer's default, trail on, t = 0 after the play
