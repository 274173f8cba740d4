"""Shared fixtures: tiny checkpoints trained by the project's own training code, and a real browser."""

from __future__ import annotations

import pytest
import torch
from gpu_machine import panda_chain

from ikdp.train import TrainConfig, train

# Tests are small; one thread avoids OpenMP spinning against other processes on a 2-core machine.
torch.set_num_threads(1)


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory):
    """A 3-link model trained for a few steps: loadable, not accurate."""
    folder = tmp_path_factory.mktemp("tiny")
    config = TrainConfig(
        joints=3,
        steps=30,
        batch=64,
        hidden=32,
        blocks=1,
        timesteps=20,
        eval_targets=20,
        save_every=1000,
        output=str(folder / "tiny.pt"),
        log_dir=str(folder / "tb"),
        threads=1,
    )
    torch.manual_seed(0)
    return train(config)


@pytest.fixture(scope="session")
def tiny_chain_checkpoint(tmp_path_factory):
    """A Panda pose model (7 joints, T = 10) trained for a few steps: loadable, not accurate."""
    folder = tmp_path_factory.mktemp("tiny_chain")
    config = TrainConfig(
        **panda_chain(),  # by name, or from the URDF carried to a GPU machine that lacks example-robot-data
        steps=5,
        batch=32,
        hidden=32,
        blocks=1,
        timesteps=10,
        eval_targets=8,
        save_every=1000,
        output=str(folder / "tiny_panda.pt"),
        log_dir=str(folder / "tb"),
        threads=1,
    )
    torch.manual_seed(0)
    return train(config)


@pytest.fixture(scope="session")
def tiny_chain_student(tiny_chain_checkpoint, tmp_path_factory):
    """(teacher path, student path, their folder): a copy of the tiny Panda model and a 2-step student distilled
    from it by ikdp.distill, in a folder of their own; the teacher's file then holds the student too (ikdp.ship), as
    a shipped model does."""
    import shutil

    from ikdp.distill import DistillConfig, distill
    from ikdp.ship import ship

    folder = tmp_path_factory.mktemp("teacher_and_student")
    teacher = shutil.copy(tiny_chain_checkpoint, folder / "panda_teacher.pt")
    config = DistillConfig(
        teacher=str(teacher), student_steps=2, teacher_steps=4, steps=3, batch=8, save_every=100, eval_targets=4,
        output=str(folder / "panda_student.pt"), log_dir=str(folder.parent / "student_tb"), threads=1,
    )  # fmt: skip
    student = distill(config)
    ship(teacher, teacher, student)
    return teacher, student, folder


@pytest.fixture(scope="module")
def browser():
    """Debian's chromium through Playwright, one per test module, seen to draw WebGL (skipped without, failed in CI)."""
    from viz_helpers import CHROMIUM_ARGS, RenderingBrowser, chromium_or_skip

    executable = chromium_or_skip()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = RenderingBrowser(playwright, executable, CHROMIUM_ARGS)
        yield browser
        browser.close()
