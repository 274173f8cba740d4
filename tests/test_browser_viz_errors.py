"""The shipped model in a real browser, on targets that broke the page before: no page error, no console error.

On `ikdp_n4`, target (-0.010, +1.200), K = 16, seed 0, DDPM, the
tip-error chart once threw `RangeError: Invalid array length` in the page. The sweep adds
a target near the base, one on the boundary and one out of reach. Every page error
and every console message of type "error" is collected; none may appear.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from viz_helpers import (
    BROWSER_TIMEOUT,
    SETTLE_IN_PAGE,
    open_page_collecting_errors,
    running_app,
    settle,
    shipped_solver_or_skip,
)

from ikdp.shipped import DEFAULT_MODEL

pytestmark = [pytest.mark.browser, pytest.mark.slow]

CHART_CRASH_TARGET = (-0.010, 1.200)


@pytest.fixture(scope="module")
def shipped_solver():
    return shipped_solver_or_skip(DEFAULT_MODEL)


def test_the_target_that_crashed_the_chart_and_a_sweep_raise_no_error_in_the_page(browser, shipped_solver):
    outer = shipped_solver.reach[1]
    sweep = {
        "chart crash": CHART_CRASH_TARGET,
        "near the base": (0.02, 0.01),
        "on the boundary": (outer * np.cos(0.7), outer * np.sin(0.7)),
        "unreachable": (5 * outer, -3 * outer),
        "inside": (0.9, -0.6),
    }
    with running_app(shipped_solver, solve_now=False, animation_seconds=1.0) as app:
        page, errors = open_page_collecting_errors(browser, app, height=1600)
        assert (app.panel.samples.value, app.panel.seed.value, app.panel.sampler.value) == (16, 0, "ddpm")
        for name, target in sweep.items():
            app.move_target(target)
            settle(app)
            app.panel.timestep.value = app.solver.timesteps // 2  # scrubbing redraws the chart too
            time.sleep(SETTLE_IN_PAGE)
            page.screenshot(timeout=BROWSER_TIMEOUT * 1000)  # chromium renders (and runs the chart's draw) for it
            assert not errors, f"{name} {target}: {errors[:3]} ({len(errors)} in all)"
        page.close()


def test_comparing_two_samplers_and_the_readable_settings_raise_no_error_in_the_page(browser, shipped_solver):
    """The chart gains and loses a series, the second workspace comes and goes, the legend and clock change."""
    with running_app(shipped_solver, solve_now=False, animation_seconds=1.0) as app:
        page, errors = open_page_collecting_errors(browser, app, height=1600)
        steps = (
            lambda: setattr(app.panel.learn.compare, "value", "ddim"),
            lambda: setattr(app.panel.learn.trail_of, "value", "all samples"),
            lambda: setattr(app.panel.learn.clock, "value", "step"),
            lambda: setattr(app.panel.learn.compare, "value", "dpmpp2m"),
            lambda: setattr(app.panel.learn.compare, "value", "off"),
        )
        app.move_target(CHART_CRASH_TARGET)
        for number, step in enumerate(steps):
            step()
            settle(app)
            app.panel.timestep.value = app.solver.timesteps // 2
            time.sleep(SETTLE_IN_PAGE)
            page.screenshot(timeout=BROWSER_TIMEOUT * 1000)
            assert not errors, f"step {number}: {errors[:3]} ({len(errors)} in all)"
        page.close()
