"""The Constraints folder in a real browser: a joint locked by a click, an obstacle, follow mode, every sample
coloured and counted; a pose model's partial target picked in the page; no page error.

Every page error and every console message of type "error" is collected; none may appear.
"""

from __future__ import annotations

import time

import numpy as np
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

import ikdp

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def wait_for(condition) -> bool:
    deadline = time.monotonic() + BROWSER_TIMEOUT
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.05)
    return condition()


def test_locking_a_joint_and_dropping_an_obstacle_in_the_page(browser):
    solver = shipped_solver_or_skip("ikdp_n4")
    with running_app(solver, animation_seconds=0.5, target=(1.5, 1.0)) as app:
        settle(app)
        controls = app.constraint_controls
        page, errors = open_page_collecting_errors(browser, app, height=1600)
        page.get_by_text("Constraints", exact=True).click()  # open the folder, as a user would
        page.get_by_text("lock θ1", exact=True).click()
        assert wait_for(lambda: controls.lock_boxes[0].value)
        settle(app)
        assert wait_for(lambda: any(c.name == "locked_joints" for c in app.solved.request.constraints))
        assert np.all(app.solved.final_angles[:, 0] == np.float32(np.radians(controls.lock_values[0].value)))
        before = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        page.get_by_text("Add obstacle", exact=True).click()
        assert wait_for(lambda: len(controls.obstacles) == 1 and controls.obstacles[0]["nodes"])
        settle(app)
        page.get_by_text("follow (one continuous solution)", exact=True).click()
        assert wait_for(lambda: controls.follow.value)
        settle(app)
        app.move_target((1.4, 1.1))
        settle(app)
        assert wait_for(lambda: "largest so far" in controls.readout.content)
        # the samples on screen are counted at the step shown, in the page's readouts
        page.get_by_text("Constraints hold", exact=True).first.wait_for(timeout=BROWSER_TIMEOUT * 1000)
        time.sleep(SETTLE_IN_PAGE)
        after = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        assert not errors, f"{errors[:3]} ({len(errors)} in all)"
        # the page drew the obstacle and the coloured states
        assert canvas_changed_share(page, before, after) > 0.005
        page.close()


def test_picking_a_partial_target_in_the_page(browser, tiny_chain_checkpoint):
    with running_app(ikdp.load(tiny_chain_checkpoint), animation_seconds=0.0) as app:
        app.panel.samples.value = 4
        settle(app)
        controls = app.constraint_controls
        page, errors = open_page_collecting_errors(browser, app, height=1600)
        page.add_style_tag(content=NO_FADE_CSS)
        page.get_by_text("Constraints", exact=True).click()
        time.sleep(SETTLE_IN_PAGE)
        before = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        page.get_by_label("target", exact=True).click()
        page.get_by_role("option", name="free z axis", exact=True).click()
        assert wait_for(lambda: controls.target_kind.value == "free z axis")
        settle(app)
        assert wait_for(lambda: [c.name for c in app.solved.request.constraints] == ["free_axis"])
        page.get_by_text("The hand's z axis free", exact=True).first.wait_for(timeout=BROWSER_TIMEOUT * 1000)
        time.sleep(SETTLE_IN_PAGE)
        after = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        assert canvas_changed_share(page, before, after) > 0.002  # the free axis and its ring are drawn
        page.get_by_label("target", exact=True).click()
        page.get_by_role("option", name="position only", exact=True).click()
        assert wait_for(lambda: app.writer.view.gizmo.disable_rotations)  # its rotation rings are hidden
        settle(app)
        page.get_by_text("Position only", exact=True).first.wait_for(timeout=BROWSER_TIMEOUT * 1000)
        assert not errors, f"{errors[:3]} ({len(errors)} in all)"
        page.close()


def sphere_pixels(page, app, sphere) -> float:
    """The share of the canvas that changes when the dropped sphere is hidden: what of it a user sees."""

    shown = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
    app.writer.run(lambda writer: setattr(sphere, "visible", False), wait=False)  # the loop writes every node
    app.writer.flush()
    time.sleep(SETTLE_IN_PAGE)
    hidden = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
    return canvas_changed_share(page, hidden, shown, threshold=25)


def test_a_dropped_obstacle_is_seen_in_front_of_the_panda(browser):
    """The Panda's dropped sphere sat inside the robot shown and could not be seen. Hiding
    it now changes a visible part of the page (dropped where it was, on the middle joint, almost none)."""
    solver = shipped_solver_or_skip("ikdp_panda")
    with running_app(solver, animation_seconds=0.0) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app)
        page.add_style_tag(content=NO_FADE_CSS)
        controls = app.constraint_controls
        controls.add_obstacle()
        settle(app)
        time.sleep(2 * SETTLE_IN_PAGE)
        seen = sphere_pixels(page, app, controls.obstacles[0]["nodes"][0])
        assert seen > 0.003, seen  # measured 0.0056 in front of it, 0.0013 on the middle joint
        assert not errors, f"{errors[:3]} ({len(errors)} in all)"
        page.close()
