"""Optimizer steps per second of a step runner (ikdp/train_steps.py's EagerSteps or GraphedSteps), as the GPU
training benchmarks time it: 10 warm-up steps (a graph's recording among them), then `windows` windows of `steps`
steps with the device synchronized at both ends; the median window's rate."""

from __future__ import annotations

import statistics
import time

import torch


def synchronize(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def steps_per_second(steps, device: torch.device, count: int, windows: int) -> float:
    for _ in range(10):
        steps(1e-4)
    rates = []
    for _ in range(windows):
        synchronize(device)
        started = time.perf_counter()
        for _ in range(count):
            steps(1e-4)
        synchronize(device)
        rates.append(count / (time.perf_counter() - started))
    return statistics.median(rates)
