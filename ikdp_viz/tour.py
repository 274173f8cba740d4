"""The guided first visit: six short steps, each one sentence and a preset view of the panel's settings.

Each step is data: what it says and the settings it puts on screen (`TourView`). `TourRunner` applies a view as a
user would set it: the model dropdown's switch, the checkboxes, the sampler, K, the target, then one solve; so what
the tour shows is what those controls show, the tests that read the page read the same controls, and leaving the
tour returns to the viewer's default view. Applying waits for model loads and solves, so it runs on a thread of its
own; a click on the next step while one is applied makes the older one stop where it is. The folder's texts and
buttons are panel outputs: the drawing loop writes them.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path

from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.intent import StateAsked

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
        TourView(timestep=0, compare="ddim"),
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


SOLVE_WAIT = 60.0  # seconds a step waits for its model and solve (a loaded machine is slow)
LEFT_TEXT = "Six short steps through what the viewer shows, each one sentence and a view."


class TourRunner:
    """The Tour folder's state: the step shown (None: the tour is left) and the view it was started from."""

    def __init__(self, app):
        self.app = app
        self.controls = app.panel.teach.tour
        self.index: int | None = None
        self.home: tuple[Path, object] | None = None  # (model path, target) the tour returns to
        self._generation = 0
        self._lock = threading.Lock()  # one view applied at a time
        self.applied = threading.Event()  # set when the newest step's view is on screen (tests wait on it)
        controls = self.controls
        controls.take.on_click(lambda _: self.start())
        controls.next.on_click(lambda _: self.show(min((self.index or 0) + 1, len(TOUR) - 1)))
        controls.back.on_click(lambda _: self.show(max((self.index or 0) - 1, 0)))
        controls.leave.on_click(lambda _: self.leave())
        self._write()

    @property
    def offered(self) -> bool:
        """The tour is about the planar arm; a robot's viewer hides it."""
        return arm_kind(self.app.solver).teaches

    def start(self) -> None:
        """Open the tour at its first step, remembering the model and target to come back to."""
        if not self.offered:
            return
        if self.index is None:
            self.home = (self.model_path(), self.app.target.copy())
        self.show(0)

    def show(self, index: int) -> None:
        if not 0 <= index < len(TOUR):
            raise ValueError(f"index: expected a tour step 0 .. {len(TOUR) - 1}, got {index}")
        if self.home is None:
            self.home = (self.model_path(), self.app.target.copy())
        self.index = index
        self._write()
        self._apply_soon(TOUR[index].view)

    def leave(self) -> None:
        """Close the tour: the default view of the model and target it began on."""
        self.index = None
        self._write()
        self._apply_soon(DEFAULT_VIEW)

    def _write(self) -> None:
        index, controls = self.index, self.controls

        def write(writer) -> None:
            controls.folder.visible = self.offered
            controls.text.content = LEFT_TEXT if index is None else tour_markdown(index)
            controls.back.visible = index is not None
            controls.back.disabled = index == 0
            controls.next.visible = index is not None
            controls.next.disabled = index == len(TOUR) - 1
            controls.leave.visible = index is not None
            controls.take.visible = index is None

        self.app.writer.run(write, wait=False)

    # ------------------------------------------------------------------ applying a view

    def _apply_soon(self, view: TourView) -> None:
        self._generation += 1
        generation = self._generation
        self.applied.clear()
        threading.Thread(target=self._apply, args=(view, generation), name="ikdp-viz-tour", daemon=True).start()

    def _apply(self, view: TourView, generation: int) -> None:
        with self._lock:
            if generation != self._generation:
                return  # a newer step was asked for meanwhile
            app, panel = self.app, self.app.panel
            home_path, home_target = self.home if self.home is not None else (self.model_path(), app.target)
            path = shipped_path(app, view.model) if view.model is not None else home_path
            if path is not None and not same_file(path, self.model_path()):
                app.load_checkpoint(path)
            panel.show_trail.value = view.show_trail
            panel.show_estimate.value = view.show_estimate
            panel.joint_space.show.value = view.joint_space
            panel.highlight.value = "best"
            panel.sampler.value = view.sampler
            panel.learn.compare.value = view.compare
            panel.samples.value = view.samples
            app.move_target(view.target if view.target is not None else home_target)
            if generation != self._generation:
                return
            app.request_solve(animate=view.timestep is None)
            app.wait_until_drawn(SOLVE_WAIT)
            if view.timestep is not None and generation == self._generation:
                app.writer.ask(state=StateAsked(timestep=float(view.timestep)))
                app.writer.flush(SOLVE_WAIT)
            if generation == self._generation:
                self.applied.set()

    def model_path(self) -> Path:
        return Path(str(self.app.solver.metadata.get("path", "")))


def same_file(first: Path, second: Path) -> bool:
    return first == second or (first.exists() and second.exists() and first.resolve() == second.resolve())


def shipped_path(app, name: str) -> Path | None:
    """The path of a shipped model `name`: from the model dropdown when it lists it, else the shipped folder."""
    for path in app.checkpoints.values():
        if Path(path).stem == name:
            return Path(path)
    from ikdp.shipped import list_shipped

    return next((path for path in list_shipped() if path.stem == name), None)
