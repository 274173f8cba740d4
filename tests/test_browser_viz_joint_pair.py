"""The joint-space view's two dropdowns in a real browser: choosing for x the joint y shows moves y
on, in the page, and the square's axis labels say the pair drawn."""

from __future__ import annotations

import time

import pytest
from viz_helpers import BROWSER_TIMEOUT, open_page_collecting_errors, running_app, settle

import ikdp

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_picking_the_same_joint_for_both_axes_moves_the_other_in_the_page(browser, tiny_checkpoint):
    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app)
        page.get_by_text("joint space view").click()
        x_joint, y_joint = page.get_by_label("x: joint"), page.get_by_label("y: joint")
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while (x_joint.is_disabled() or y_joint.input_value() != "θ2") and time.monotonic() < deadline:
            time.sleep(0.05)  # the view is drawn: the arm's three joints offered
        x_joint.click()
        page.get_by_role("option", name="θ2", exact=True).click()  # the joint the y axis shows
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while y_joint.input_value() != "θ3" and time.monotonic() < deadline:
            time.sleep(0.05)
        assert (x_joint.input_value(), y_joint.input_value()) == ("θ2", "θ3")  # y moved on, visibly
        app.writer.flush()
        assert app.panel.joint_space.joints() == (1, 2)
        assert [label.text for label in app.writer.stage.joint_space.labels[:2]] == ["θ2", "θ3"]
        assert not errors, errors
        page.close()
