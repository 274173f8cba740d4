"""Plays the denoising, state after state, on its own thread, in real time.

The state shown is the one the clock has reached, so a slow frame skips states
rather than slowing the animation: it always ends on the last state after the
set duration. A frame is drawn with the player's lock held, so `play()` and
`pause()` return only between frames and no frame of an older animation can be
drawn after them.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable


class Player:
    """Calls draw(state) for states first..last over `seconds_per_state` each."""

    def __init__(self, draw: Callable[[int], None], *, frames_per_second: float = 30.0, clock=time.monotonic):
        self._draw = draw
        self._frame_seconds = 1.0 / frames_per_second
        self._clock = clock
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._playing = False
        self._first = self._last = self._shown = 0
        self._seconds_per_state = 0.0
        self._started_at = 0.0
        self._closed = False
        self._thread: threading.Thread | None = None  # started by the first play(), not at construction

    @property
    def playing(self) -> bool:
        return self._playing

    def play(self, first: int, last: int, seconds_per_state: float, *, first_shown: bool = False) -> None:
        """Animate from state `first` to `last`; `first_shown`: the caller has drawn `first` already."""
        with self._wake:
            if self._closed:
                return
            self._first, self._last = first, last
            self._seconds_per_state = max(0.0, seconds_per_state)
            self._started_at = self._clock()
            self._shown = first if first_shown else -1
            self._playing = True
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="ikdp-viz-player", daemon=True)
                self._thread.start()
            self._wake.notify_all()

    def pause(self) -> None:
        """Stop after the frame being drawn, if any."""
        with self._wake:
            self._playing = False

    def interrupt(self) -> None:
        """Stop soon, without waiting for a frame being drawn: safe to call from an event loop.

        Unlike pause(), a frame already being drawn may still land after it returns.
        """
        self._playing = False

    def close(self, timeout: float = 2.0) -> None:
        with self._wake:
            self._closed, self._playing = True, False
            self._wake.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    def state_at(self, now: float) -> int:
        """The state the clock has reached at time `now`."""
        if self._seconds_per_state <= 0:
            return self._last
        reached = self._first + int((now - self._started_at) / self._seconds_per_state)
        return min(self._last, reached)

    def _run(self) -> None:
        with self._wake:
            while not self._closed:
                if not self._playing:
                    self._wake.wait()
                    continue
                state = self.state_at(self._clock())
                if state != self._shown:
                    try:
                        self._draw(state)
                    except Exception:
                        traceback.print_exc()  # a failed frame stops this animation, not the player
                        self._playing = False
                        continue
                    self._shown = state
                if state >= self._last:
                    self._playing = False
                    continue
                self._wake.wait(self._frame_seconds)
