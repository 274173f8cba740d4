"""What the user, the solve worker and scripts ask of the drawing loop: the fields of one `Intent`, and the clock.

A callback's whole work is to set a field (`Asked.ask`); the drawing loop (scene_writer.py) takes
the value each pass, leaving an empty one, and does what it asks in a fixed order. Asking twice
before the loop looks keeps the newest target, solve, state and model: nothing is queued behind
a stale one, and no handler runs inside another.
"""

from __future__ import annotations

import threading
import traceback
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class TargetMove:
    target: np.ndarray  # where the cross goes
    clamped: bool  # the asked point lay outside the workspace
    move_gizmo: bool  # write the gizmo's position (False: the page's drag already put it there)
    force: bool  # send the position even when the server's copy holds it already


@dataclass(frozen=True)
class StateAsked:
    state: int | None = None  # a state index (0 = pure noise .. S = final), or
    timestep: float | None = None  # the state nearest this diffusion time
    delta: int = 0  # added to the state on screen (previous / next buttons)


@dataclass
class Intent:
    """Everything asked since the loop last looked. Empty fields ask nothing."""

    model: tuple | None = None  # (solver, target): rebuild the scene for this model
    tabs: list = field(default_factory=list)  # browser tabs that connected (viser ClientHandles)
    changed: list = field(default_factory=list)  # names of controls whose handler writes other controls
    chores: list = field(default_factory=list)  # functions of the writer from long work: an export's notes
    target: TargetMove | None = None  # the newest target's place
    solve: tuple | None = None  # (arrival, animate): solve the newest target with the panel's settings
    solved: tuple | None = None  # (Solved, newest): the newest finished solve, to draw in place of the one shown
    fields: tuple | None = None  # (Solved, joint_space.SolveFields): joint-space fields computed for a solve on screen
    replay: np.ndarray | None = None  # a drag ended at this target: play its solve from t = T once drawn
    prior: np.ndarray | None = None  # (K, N+1, d) poses drawn from the prior, shown until the next solve
    error: str | None = None  # why the newest solve failed
    state: StateAsked | None = None  # a state to show (pauses the animation)
    toggle_play: bool = False  # pause, or play from the state shown
    redraw: bool = False  # a view setting changed: draw the state on screen again

    def empty(self) -> bool:
        """Nothing asked (field by field: `==` on the arrays some fields hold has no single truth)."""
        return (
            all(
                value is None
                for value in (
                    self.model,
                    self.target,
                    self.solve,
                    self.solved,
                    self.fields,
                    self.replay,
                    self.prior,
                    self.error,
                    self.state,
                )
            )  # fmt: skip
            and not (self.tabs or self.changed or self.chores or self.toggle_play or self.redraw)
        )


class Asked:
    """The intent not yet taken, and the loop's thread that takes it: at once when asked, else every `wait()` s."""

    def __init__(self, apply, *, wait, failed):
        self._apply, self._wait, self._failed = apply, wait, failed
        self._condition = threading.Condition()
        self._intent = Intent()
        self._asked = 0  # asks so far
        self._done = 0  # asks the loop has finished applying
        self._closed = False
        self._thread: threading.Thread | None = None

    @property
    def idle(self) -> bool:
        """Nothing asked that the loop has not finished."""
        with self._condition:
            return self._done == self._asked

    def on_thread(self) -> bool:
        return threading.current_thread() is self._thread

    def ask(self, **fields) -> None:
        """Set fields of the intent (any thread). The newest value of a field wins; a delta of states adds up, a
        play toggle flips, tabs, control names and chores are kept in order."""
        with self._condition:
            if self._closed:
                return
            intent = self._intent
            for name, value in fields.items():
                if name in ("tabs", "changed", "chores"):
                    getattr(intent, name).extend(value)
                elif name == "toggle_play":
                    intent.toggle_play = intent.toggle_play != bool(value)
                elif name == "state" and intent.state is not None and value.delta and intent.state.delta:
                    intent.state = StateAsked(delta=intent.state.delta + value.delta)
                elif name == "target" and intent.target is not None:  # the gizmo follows if any move asked it
                    old = intent.target
                    intent.target = TargetMove(value.target, value.clamped, value.move_gizmo or old.move_gizmo,
                                               value.force or old.force)  # fmt: skip
                else:
                    setattr(intent, name, value)
            self._asked += 1
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="ikdp-viz-scene", daemon=True)
                self._thread.start()
            self._condition.notify_all()

    def flush(self, timeout: float = 30.0) -> bool:
        """Block until everything asked so far has been applied (True), or `timeout` passes (False)."""
        if self.on_thread():
            return True
        with self._condition:
            wanted = self._asked
            return self._condition.wait_for(lambda: self._done >= wanted or self._closed, timeout)

    def close(self, timeout: float = 2.0) -> None:
        with self._condition:
            self._closed, thread = True, self._thread
            self._condition.notify_all()
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    def _run(self) -> None:
        while True:
            with self._condition:
                if self._intent.empty() and not self._closed:
                    self._condition.wait(self._wait())
                if self._closed:
                    return
                intent, self._intent, asked = self._intent, Intent(), self._asked
            try:
                self._apply(intent)  # an empty intent: the clock ticked
            except Exception:
                traceback.print_exc()  # a failed frame is reported; the loop goes on
                self._failed()
            with self._condition:
                self._done = max(self._done, asked)
                self._condition.notify_all()


@dataclass
class Animation:
    """The clock of one playing of the denoising: state first at `started_at`, one state per `seconds_per_state`."""

    first: int  # the state shown when it started
    last: int  # the state it ends on
    seconds_per_state: float  # 0: jump to the last state
    started_at: float  # time.monotonic() when `first` was shown
    offsets: np.ndarray | None = None  # (S+1,) when each state shows, seconds from state 0 (frame.py); None: evenly

    def state_at(self, now: float) -> int:
        """The state the clock has reached at `now`: a slow frame skips states, it never slows the animation."""
        if self.seconds_per_state <= 0:
            return self.last
        if self.offsets is not None:
            elapsed = now - self.started_at + self.offsets[self.first]
            reached = int(np.searchsorted(self.offsets, elapsed, side="right")) - 1
            return int(np.clip(reached, self.first, self.last))
        return min(self.last, self.first + int((now - self.started_at) / self.seconds_per_state))
