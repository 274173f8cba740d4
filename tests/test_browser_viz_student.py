"""The teacher's full denoising one click away in a real browser: the button sits in the
Denoising folder, open from the start, and one click there switches the robot from its student to the teacher."""

from __future__ import annotations

import time

import pytest
from viz_helpers import BROWSER_TIMEOUT, open_page_collecting_errors, running_app, settle

import ikdp
from ikdp_viz.student import STUDENT

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_one_click_in_the_page_shows_the_teachers_full_denoising(browser, tiny_chain_student):
    teacher, _, folder = tiny_chain_student
    with running_app(ikdp.load(teacher), animation_seconds=0.0, checkpoint_folder=folder) as app:
        app.panel.sampler.value = STUDENT
        settle(app)
        page, errors = open_page_collecting_errors(browser, app)
        try:
            page.get_by_role("button", name="Show the teacher (DDPM, 10 steps)").click(timeout=BROWSER_TIMEOUT * 1000)
            deadline = time.monotonic() + BROWSER_TIMEOUT
            while app.panel.sampler.value != "ddpm" and time.monotonic() < deadline:
                time.sleep(0.05)
            settle(app)
            assert app.panel.sampler.value == "ddpm" and app.solved.request.solver is app.solver
            assert app.solved.view.num_states == app.solver.timesteps + 1  # the teacher's every step
            page.get_by_role("button", name="Show the student (DDIM, 2 steps)").wait_for(timeout=BROWSER_TIMEOUT * 1000)
            assert errors == []
        finally:
            page.close()
