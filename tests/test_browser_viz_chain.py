"""A robot's checkpoint in a real browser: the 3-D view opens, draws a solve, and the page logs no error.

A tiny Panda model; every page error and every console message of type "error" is
collected while the page loads, a solve is drawn and animated, the slider is moved
and refine is switched on; none may appear.
"""

from __future__ import annotations

import time

import pytest
from viz_helpers import (
    BROWSER_TIMEOUT,
    NO_FADE_CSS,
    SETTLE_IN_PAGE,
    open_page_collecting_errors,
    read_png,
    running_app,
    settle,
)

import ikdp

pytestmark = [pytest.mark.browser, pytest.mark.slow]

BACKGROUND = 250  # viser's canvas is white; a drawn robot is darker than this


def test_a_chain_checkpoint_opens_and_draws_a_solve_without_page_errors(browser, tiny_chain_checkpoint):
    with running_app(ikdp.load(tiny_chain_checkpoint), solve_now=False, animation_seconds=1.0) as app:
        page, errors = open_page_collecting_errors(browser, app)
        page.add_style_tag(content=NO_FADE_CSS)
        app.panel.samples.value = 4  # solves the first target, animated from t = T
        settle(app)
        assert app.solved is not None and app.state == app.solved.view.num_states - 1
        # the readouts reached the page
        page.get_by_text("Hand error", exact=False).first.wait_for(timeout=BROWSER_TIMEOUT * 1000)
        app.panel.timestep.value = app.solver.timesteps // 2
        app.panel.refine.value = True
        settle(app)
        time.sleep(SETTLE_IN_PAGE)
        image = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        assert not errors, f"{errors[:3]} ({len(errors)} in all)"
        scene = image[:, : image.shape[1] // 2]  # left of the panel: the robots stand there
        assert (scene.max(axis=-1) < BACKGROUND - 60).mean() > 0.002, "nothing dark drawn in the scene"
        page.close()
