"""A worker thread on which the newest request always wins.

At most one job runs and at most one waits. Submitting replaces the waiting job
(it is dropped unstarted) and asks the running one to stop: a job is handed a
`cancel` event, and one that notices it raises `Cancelled` and is dropped. A job
that finishes after a newer one was submitted is dropped too: its result is for
a stale target. So requests never queue up behind a slow solve, and what gets
drawn is always the newest target.

One exception keeps a fast stream of requests from starving the screen when
every job takes longer than the gap between requests (each would be cancelled
or finish stale): with `stale_grace` set, once nothing has been delivered for
that many seconds the running job is left to finish and its result is
delivered. It is older than the newest request, never older than what is on
screen.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

Job = Callable[[threading.Event], Any]  # job(cancel) -> result; may raise Cancelled once `cancel` is set


class Cancelled(Exception):
    """Raised by a job that stopped because a newer one was submitted."""


@dataclass
class WorkerStats:
    submitted: int = 0  # jobs handed to submit()
    replaced: int = 0  # dropped before they started: a newer job arrived while they waited
    cancelled: int = 0  # stopped part-way: a newer job arrived while they ran
    stale: int = 0  # ran to the end, but a newer job had arrived: result dropped
    delivered: int = 0  # results handed to on_done
    late: int = 0  # of those, stale ones delivered because nothing had been for `stale_grace` seconds
    failed: int = 0  # jobs that raised


class LatestWorker:
    """Runs `job(cancel)` on one daemon thread, then `on_done(ticket, result)` there if it is still the newest."""

    def __init__(self, name: str = "ikdp-viz-solve", *, stale_grace: float | None = None):
        self._name = name
        self.stale_grace = stale_grace  # seconds without a delivery after which a running job is left to finish
        self._last_delivery = time.monotonic()
        self._condition = threading.Condition()
        self._waiting: tuple[int, Job, Callable[[int, Any], None], Callable | None] | None = None
        self._newest = 0  # ticket of the newest submission
        self._running: int | None = None  # ticket of the job running now
        self._cancel = threading.Event()  # the running job's
        self._closed = False
        self._thread: threading.Thread | None = None  # started by the first submit, not at construction
        self.stats = WorkerStats()

    def submit(
        self,
        job: Job,
        on_done: Callable[[int, Any], None],
        on_error: Callable[[int, BaseException], None] | None = None,
    ) -> int:
        """Queue `job` in place of any waiting one and ask the running one to stop; returns its ticket."""
        with self._condition:
            if self._closed:
                raise RuntimeError("LatestWorker: submit after close()")
            self._newest += 1
            if self._waiting is not None:
                self.stats.replaced += 1
            self._waiting = (self._newest, job, on_done, on_error)
            self.stats.submitted += 1
            if self._running is not None and not self._starving():
                self._cancel.set()
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
                self._thread.start()
            self._condition.notify_all()
            return self._newest

    def is_newest(self, ticket: int) -> bool:
        with self._condition:
            return ticket == self._newest

    @property
    def idle(self) -> bool:
        """Nothing waiting and nothing running."""
        with self._condition:
            return self._waiting is None and self._running is None

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until idle (True) or `timeout` seconds pass (False)."""
        with self._condition:
            return self._condition.wait_for(lambda: self._waiting is None and self._running is None, timeout)

    def close(self, timeout: float = 5.0) -> None:
        """Drop the waiting job, stop the running one, and end the thread."""
        with self._condition:
            self._closed = True
            self._waiting = None
            self._cancel.set()
            self._condition.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    def _starving(self) -> bool:
        return self.stale_grace is not None and time.monotonic() - self._last_delivery > self.stale_grace

    def _run(self) -> None:
        while True:
            with self._condition:
                self._condition.wait_for(lambda: self._waiting is not None or self._closed)
                if self._closed:
                    return
                ticket, job, on_done, on_error = self._waiting
                self._waiting, self._running = None, ticket
                self._cancel = cancel = threading.Event()
            try:
                try:
                    result = job(cancel)
                except Cancelled:
                    self.stats.cancelled += 1
                    continue
                except Exception as error:  # a failed solve must not kill the worker
                    self.stats.failed += 1
                    if on_error is not None and self.is_newest(ticket):
                        on_error(ticket, error)
                    elif on_error is None:
                        traceback.print_exc()
                    continue
                with self._condition:
                    newest = ticket == self._newest
                    starving = self._starving()
                if newest or starving:
                    self.stats.delivered += 1
                    self.stats.late += not newest
                    self._last_delivery = time.monotonic()
                    on_done(ticket, result)
                else:
                    self.stats.stale += 1
            except Exception:
                traceback.print_exc()  # a failed draw is reported, and the worker goes on
            finally:
                with self._condition:
                    self._running = None
                    self._condition.notify_all()
