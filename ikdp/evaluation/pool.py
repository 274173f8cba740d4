"""A pool of single-threaded worker processes, for the evaluation's independent runs.

On a small machine the models here use a second thread poorly: two processes of one
thread each keep both cores busy where one process of two threads would not.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor

import torch


def _single_threaded() -> None:
    torch.set_num_threads(1)


@contextlib.contextmanager
def single_threaded_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A ProcessPoolExecutor of `workers` processes, each with one torch and one OpenMP thread."""
    if workers < 1:
        raise ValueError(f"workers: expected a positive integer, got {workers}")
    # spawn, not fork: a forked child inherits the parent's OpenMP state and can hang in its first parallel region.
    # OpenMP reads OMP_NUM_THREADS when torch loads in a worker, before any initializer runs: set it around the
    # pool (workers start inside it and inherit the environment), then put the parent's back.
    saved = os.environ.get("OMP_NUM_THREADS")
    os.environ["OMP_NUM_THREADS"] = "1"
    try:
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=context, initializer=_single_threaded) as pool:
            yield pool
    finally:
        if saved is None:
            os.environ.pop("OMP_NUM_THREADS", None)
        else:
            os.environ["OMP_NUM_THREADS"] = saved
