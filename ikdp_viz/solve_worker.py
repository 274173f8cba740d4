"""A worker thread on which the newest request always wins.

At most one job runs and at most one waits. Submitting replaces the waiting job
(it is dropped unstarted), so requests never queue up behind a slow solve, and
it stops the running job if that is less than `cancel_fraction` of the way
through (judged by the last job's duration): a job is handed a `cancel` event,
and one that notices it raises `Cancelled` and is dropped. A job further along
is left to finish, because finishing it refreshes the screen sooner than
starting over would; its result is delivered and the newest job starts right
after. Results arrive in submission order, so nothing older ever replaces
something newer on screen.

So that a fast stream of requests cannot cancel every job in turn and starve
the screen, no job is cancelled once nothing has been delivered for
`stale_grace` seconds.
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
    cancelled: int = 0  # stopped part-way: a newer job arrived early in their run
    delivered: int = 0  # results handed to on_done
    late: int = 0  # of those, jobs a newer one arrived during, too late in their run to cancel them
    failed: int = 0  # jobs that raised


class LatestWorker:
    """Runs `job(cancel)` on one daemon thread, then `on_done(ticket, result)` there unless it was cancelled."""

    def __init__(self, name: str = "ikdp-viz-solve", *, cancel_fraction: float = 0.5, stale_grace: float | None = None):
        self._name = name
        self.cancel_fraction = cancel_fraction  # a running job this far through (of the last one's time) is kept
        self.stale_grace = stale_grace  # seconds without a delivery after which no job is cancelled
        self._last_delivery = time.monotonic()
        self._last_seconds: float | None = None  # how long the last finished job ran
        self._started = 0.0  # when the running job started
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
        """Queue `job` in place of any waiting one, stop the running one if early in its run; returns its ticket."""
        with self._condition:
            if self._closed:
                raise RuntimeError("LatestWorker: submit after close()")
            self._newest += 1
            if self._waiting is not None:
                self.stats.replaced += 1
            self._waiting = (self._newest, job, on_done, on_error)
            self.stats.submitted += 1
            if self._running is not None and self._worth_cancelling():
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

    def _worth_cancelling(self) -> bool:
        now = time.monotonic()
        if self.stale_grace is not None and now - self._last_delivery > self.stale_grace:
            return False  # the screen has waited long enough: let this one finish
        return self._last_seconds is None or now - self._started < self.cancel_fraction * self._last_seconds

    def _run(self) -> None:
        while True:
            with self._condition:
                self._condition.wait_for(lambda: self._waiting is not None or self._closed)
                if self._closed:
                    return
                ticket, job, on_done, on_error = self._waiting
                self._waiting, self._running = None, ticket
                self._cancel = cancel = threading.Event()
                self._started = time.monotonic()
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
                    self._last_seconds = time.monotonic() - self._started
                self.stats.delivered += 1
                self.stats.late += not newest
                self._last_delivery = time.monotonic()
                on_done(ticket, result)
            except Exception:
                traceback.print_exc()  # a failed draw is reported, and the worker goes on
            finally:
                with self._condition:
                    self._running = None
                    self._condition.notify_all()
