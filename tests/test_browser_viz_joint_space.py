"""The joint-space view in a real browser: turned on, played, scrubbed, on a curve of solutions; no page error.

Every page error and every console message of type "error" is collected; none may appear.
"""

from __future__ import annotations

import time

import pytest
from viz_helpers import (
    BROWSER_TIMEOUT,
    SETTLE_IN_PAGE,
    canvas_changed_share,
    open_page_collecting_errors,
    read_png,
    running_app,
    settle,
    shipped_solver_or_skip,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow]


@pytest.mark.parametrize("name", ["ikdp_n2", "ikdp_n4"])
def test_turning_the_joint_space_view_on_raises_no_error_in_the_page(browser, name):
    solver = shipped_solver_or_skip(name)
    with running_app(solver, animation_seconds=1.0, target=(1.2, 0.5)) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app)
        before = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        page.get_by_text("joint space view").click()  # as a user would: the checkbox's label
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while not app.writer.stage.joint_space.shown and time.monotonic() < deadline:
            time.sleep(0.05)
        assert app.writer.stage.joint_space.shown
        app.toggle_play()  # the denoising plays with the view on
        settle(app)
        app.panel.timestep.value = app.solver.timesteps // 2
        if name == "ikdp_n4":
            app.panel.joint_space.second.value = "θ4"
        app.move_target((0.0, 0.0))  # the base: for l1 = l2 a curve of solutions
        settle(app)
        time.sleep(SETTLE_IN_PAGE)
        after = read_png(page.screenshot(timeout=BROWSER_TIMEOUT * 1000))
        assert not errors, f"{errors[:3]} ({len(errors)} in all)"
        # the page drew something new: the camera moved out and the square appeared
        assert canvas_changed_share(page, before, after) > 0.02
        page.close()
