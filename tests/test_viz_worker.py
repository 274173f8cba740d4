"""The newest-wins solve worker and the animation clock, driven by events and given times, never by sleeps."""

from __future__ import annotations

import threading

from ikdp_viz.intent import Animation
from ikdp_viz.solve_worker import Cancelled, LatestWorker


def test_waiting_requests_are_replaced_and_a_job_too_far_along_to_cancel_shows_before_the_newest():
    worker = LatestWorker(cancel_fraction=0.0)  # never cancel a job once one has finished
    worker.submit(lambda cancel: "history", lambda ticket, result: None)
    assert worker.wait_idle(10)
    started, release = threading.Event(), threading.Event()
    ran, delivered = [], []

    def job(name):
        def run(cancel):
            ran.append(name)
            if name == "first":
                started.set()
                assert release.wait(10)  # deaf to `cancel`: runs to the end
            return name

        return run

    def on_done(ticket, result):
        delivered.append((ticket, result))

    worker.submit(job("first"), on_done)
    assert started.wait(10)
    for name in ("second", "third", "fourth"):  # arrive while "first" runs: each replaces the one waiting
        worker.submit(job(name), on_done)
    assert not worker.idle
    release.set()
    assert worker.wait_idle(10)
    assert ran == ["first", "fourth"]  # second and third never ran
    assert delivered == [(2, "first"), (5, "fourth")]  # in order: nothing older follows something newer
    stats = worker.stats
    assert (stats.submitted, stats.replaced, stats.late, stats.delivered, stats.cancelled) == (5, 2, 1, 3, 0)
    assert worker.is_newest(5) and not worker.is_newest(2)
    worker.close()


def test_a_newer_request_stops_a_running_job_early_in_its_run():
    worker = LatestWorker()  # no job has finished yet: any running one is early
    started, delivered = threading.Event(), []

    def listening(cancel):
        started.set()
        assert cancel.wait(10)  # a solve checks between its steps
        raise Cancelled

    worker.submit(listening, lambda ticket, result: delivered.append(result))
    assert started.wait(10)
    worker.submit(lambda cancel: "newest", lambda ticket, result: delivered.append(result))
    assert worker.wait_idle(10)
    assert delivered == ["newest"] and worker.stats.cancelled == 1 and worker.stats.late == 0
    worker.close()


def test_with_a_grace_a_starved_screen_gets_the_running_job_rather_than_nothing():
    worker = LatestWorker(cancel_fraction=float("inf"), stale_grace=0.0)  # would cancel, but the screen waited
    started, release = threading.Event(), threading.Event()
    delivered, cancelled = [], []

    def slow(cancel):
        started.set()
        assert release.wait(10)
        cancelled.append(cancel.is_set())
        return "old"

    worker.submit(slow, lambda ticket, result: delivered.append(result))
    assert started.wait(10)
    worker.submit(lambda cancel: "new", lambda ticket, result: delivered.append(result))
    release.set()
    assert worker.wait_idle(10)
    assert cancelled == [False]  # not asked to stop
    assert delivered == ["old", "new"] and worker.stats.late == 1 and worker.stats.cancelled == 0
    worker.close()


def test_a_failing_job_is_reported_and_the_worker_goes_on():
    worker = LatestWorker()
    errors, delivered = [], []

    def broken(cancel):
        raise RuntimeError("solver exploded")

    worker.submit(
        broken, lambda ticket, result: delivered.append(result), lambda ticket, error: errors.append(str(error))
    )
    assert worker.wait_idle(10)
    worker.submit(lambda cancel: 42, lambda ticket, result: delivered.append(result))
    assert worker.wait_idle(10)
    assert errors == ["solver exploded"] and delivered == [42] and worker.stats.failed == 1
    worker.close()


def test_a_worker_starts_its_thread_only_when_asked_and_stops_on_close():
    before = threading.active_count()
    worker = LatestWorker()
    assert threading.active_count() == before and worker.idle
    worker.submit(lambda cancel: None, lambda ticket, result: None)
    assert worker.wait_idle(10)
    worker.close()
    assert threading.active_count() == before


def test_the_animation_clock_skips_states_rather_than_slowing_and_ends_on_the_last():
    animation = Animation(first=0, last=10, seconds_per_state=0.1, started_at=100.0)
    # frames drawn 0.25 s apart: the clock skips states, it never lags behind real time
    assert [animation.state_at(100.0 + 0.25 * frame) for frame in range(6)] == [0, 2, 5, 7, 10, 10]
    resumed = Animation(first=5, last=8, seconds_per_state=1.0, started_at=0.0)  # played from a shown state
    assert [resumed.state_at(now) for now in (0.0, 0.99, 1.0, 2.5, 9.0)] == [5, 5, 6, 7, 8]
    assert Animation(first=0, last=8, seconds_per_state=0.0, started_at=0.0).state_at(0.0) == 8  # no duration
