"""A kinematic tree (the shipped Unitree G1, both hands) in a real browser: the robot is drawn, a new target for one
hand changes the picture, and the page's readout names both hands; the page logs no error."""

from __future__ import annotations

import time

import pytest
from viz_helpers import (
    BROWSER_TIMEOUT,
    NO_FADE_CSS,
    SETTLE_IN_PAGE,
    canvas_changed_share,
    open_page_collecting_errors,
    read_png,
    running_app,
    settle,
    shipped_solver_or_skip,
)

from ikdp_viz.chain_kind import TreeKind

pytestmark = [pytest.mark.browser, pytest.mark.slow]

BACKGROUND = 250  # viser's canvas is white; a drawn robot is darker than this


def test_the_g1_is_drawn_and_moving_one_hands_target_changes_the_picture(browser):
    solver = shipped_solver_or_skip("ikdp_g1")
    with running_app(solver, solve_now=False, animation_seconds=0.0) as app:
        page, errors = open_page_collecting_errors(browser, app)
        page.add_style_tag(content=NO_FADE_CSS)
        app.panel.sampler.value = "dpmpp2m"
        app.panel.steps.value = 10
        app.panel.samples.value = 4  # solves the first target
        settle(app)
        for name in ("left_rubber_hand", "right_rubber_hand"):  # the readout on the page names each hand
            page.get_by_text(f"{name}:", exact=False).first.wait_for(timeout=BROWSER_TIMEOUT * 1000)
        time.sleep(SETTLE_IN_PAGE)
        before = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        scene = before[:, : before.shape[1] // 2]
        assert (scene.max(axis=-1) < BACKGROUND - 60).mean() > 0.002, "nothing dark drawn in the scene"

        kind, arm = TreeKind(), app.solver.arm
        rows = kind.pose_rows(arm, app.target)
        rows[1, :3] += (0.1, -0.1, 0.15)  # the right hand's target up and out
        app.move_target(kind.flat_target(arm, rows))
        settle(app)
        time.sleep(SETTLE_IN_PAGE)
        after = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        assert canvas_changed_share(page, before, after) > 0.002, "moving a hand's target changed no pixel"
        assert not errors, f"{errors[:3]} ({len(errors)} in all)"
        page.close()
