"""A queue and the one thread that empties it: the drawing loop's clock and mailbox (scene_writer.py).

Any thread may `post` a message; the loop's thread applies them one at a time, in order, and
between them calls `tick` at the pace `wait()` asks (the animation's frames), so the loop is
also the playback clock. The thread starts with the first message, not at construction
(importing or building the app starts nothing).
"""

from __future__ import annotations

import queue
import threading
import traceback

from ikdp_viz.messages import Barrier


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
