"""What other threads ask of the drawing loop (scene_writer.py), as plain values, and the animation's clock.

Callbacks and the solve worker only record intent: each posts one of these, and the loop
applies them in order on its own thread, the one thread that writes the browser's view.
"""

from __future__ import annotations

import queue
import threading
import traceback
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


# A queue and the one thread that empties it: the drawing loop's clock and mailbox (scene_writer.py).
class MessageLoop:
    """One thread applying posted messages in order; `tick()` between them, at most `wait()` seconds apart."""

    def __init__(self, apply, tick, *, wait, failed):
        self._apply, self._tick, self._wait, self._failed = apply, tick, wait, failed
        self._queue: queue.Queue = queue.Queue()
        self._busy = False  # a message is being applied
        self._closed = False
        self._thread: threading.Thread | None = None
        self._thread_lock = threading.Lock()

    @property
    def idle(self) -> bool:
        """No message waiting or being applied."""
        return self._queue.empty() and not self._busy

    def on_thread(self) -> bool:
        return threading.current_thread() is self._thread

    def post(self, message) -> None:
        """Queue `message` for the loop's thread (any thread may post)."""
        with self._thread_lock:
            if self._closed:
                return
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="ikdp-viz-scene", daemon=True)
                self._thread.start()
        self._queue.put(message)

    def run(self, message, *, wait: bool) -> None:
        """Apply `message` on the loop's thread: now when already on it, else posted (and waited for, when `wait`)."""
        if self.on_thread():
            self._apply(message)
        else:
            self.post(message)
            if wait:
                self.flush()

    def flush(self, timeout: float = 30.0) -> bool:
        """Block until every message posted so far has been applied (True), or `timeout` passes (False)."""
        if self.on_thread():
            return True
        done = threading.Event()
        self.post(Barrier(done))
        return done.wait(timeout) or self._closed

    def close(self, timeout: float = 2.0) -> None:
        with self._thread_lock:
            self._closed, thread = True, self._thread
        self._queue.put(None)
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    def _run(self) -> None:
        while True:
            try:
                message = self._queue.get(timeout=self._wait())
            except queue.Empty:
                message = ()  # the clock ticked
            if message is None:
                return
            self._busy = True
            try:
                if isinstance(message, Barrier):
                    message.done.set()
                elif message != ():
                    self._apply(message)
                self._tick()
            except Exception:
                traceback.print_exc()  # a failed frame is reported; the loop goes on
                self._failed()
            finally:
                self._busy = False
