"""What other threads ask of the drawing loop (scene_writer.py), as plain values, and the animation's clock.

Callbacks and the solve worker only record intent: each posts one of these, and the loop
applies them in order on its own thread, the one thread that writes the browser's view.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

import ikdp
from ikdp_viz.solving import Solved


@dataclass(frozen=True)
class ShowSolve:
    solved: Solved  # a finished solve, to draw in place of the one on screen
    newest: bool  # its target was still the newest when it finished (for the latency benchmark)


@dataclass(frozen=True)
class ShowState:
    state: int | None = None  # a state index (0 = pure noise .. S = final), or
    timestep: float | None = None  # the state nearest this diffusion time
    delta: int = 0  # added to the state on screen (previous / next buttons)


@dataclass(frozen=True)
class TogglePlay:
    pass


@dataclass(frozen=True)
class ReplayWhenDrawn:
    target: np.ndarray  # (2,) a drag ended here: play its solve from t = T, now if on screen, else once drawn


@dataclass(frozen=True)
class Redraw:
    pass  # the highlight, trail or x̂0 setting changed: draw the state on screen again


@dataclass(frozen=True)
class PlaceTarget:
    target: np.ndarray  # (2,) where the cross goes
    clamped: bool  # the asked point lay outside the workspace
    move_gizmo: bool  # write the gizmo's position (False: the page's drag already put it there)
    force: bool  # send the position even when the server's copy holds it already


@dataclass(frozen=True)
class NewModel:
    solver: ikdp.Solver  # rebuild the scene for this model; solves of any other are dropped
    target: np.ndarray  # (2,) the cross's place in the new workspace


@dataclass(frozen=True)
class ShowPrior:
    joints: np.ndarray  # (K, N+1, 2) poses drawn from the model's prior, shown until the next solve


@dataclass(frozen=True)
class ShowError:
    text: str  # why the newest solve failed


@dataclass(frozen=True)
class TabOpened:
    client: object  # a browser tab connected (viser.ClientHandle): play a solve no one has seen yet


@dataclass(frozen=True)
class Call:
    function: object  # called on the writer's thread with the writer: for the panel's exports and tests


@dataclass(frozen=True)
class Barrier:
    done: threading.Event  # set once every message posted before it has been applied


@dataclass
class Animation:
    """The clock of one playing of the denoising: state first at `started_at`, one state per `seconds_per_state`."""

    first: int  # the state shown when it started
    last: int  # the state it ends on
    seconds_per_state: float  # 0: jump to the last state
    started_at: float  # time.monotonic() when `first` was shown
    offsets: np.ndarray | None = None  # (S+1,) when each state shows, seconds from state 0 (clock.py); None: evenly

    def state_at(self, now: float) -> int:
        """The state the clock has reached at `now`: a slow frame skips states, it never slows the animation."""
        if self.seconds_per_state <= 0:
            return self.last
        if self.offsets is not None:
            elapsed = now - self.started_at + self.offsets[self.first]
            reached = int(np.searchsorted(self.offsets, elapsed, side="right")) - 1
            return int(np.clip(reached, self.first, self.last))
        return min(self.last, self.first + int((now - self.started_at) / self.seconds_per_state))
