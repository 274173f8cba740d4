"""The readouts' chart in a real browser: hovering it shows no stray dot and no "now: NaN", the legend
is one line, and the top decade's tick label has room above the plot area."""

from __future__ import annotations

import time

import pytest
from viz_helpers import BROWSER_TIMEOUT, open_page_collecting_errors, running_app, settle

import ikdp

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_hovering_the_chart_shows_no_stray_dot_nor_nan_and_the_legend_is_one_line(browser, tiny_checkpoint):
    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app, height=1400)
        for folder in ("Denoising", "Noise schedule", "Joint space", "Sampling"):  # folded, so the chart is in view
            page.get_by_text(folder, exact=True).first.click()
        chart = page.locator(".uplot", has_text="error against t").first  # the Readouts' chart, not the schedule's
        chart.wait_for(timeout=BROWSER_TIMEOUT * 1000)
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while "tip error against t" not in chart.inner_text() and time.monotonic() < deadline:
            time.sleep(0.05)  # the first solve's title, axes and data have arrived
        over = chart.locator(".u-over").first.bounding_box()
        for share in (0.2, 0.5, 0.8):  # off the current state (t = 0, at the left), where "now" is NaN
            page.mouse.move(over["x"] + share * over["width"], over["y"] + 0.5 * over["height"])
            time.sleep(0.3)
            legend = chart.locator(".u-legend").first
            assert "NaN" not in legend.inner_text() and "nan" not in chart.inner_text().lower()
            dots = chart.locator(".u-cursor-pt").evaluate_all(
                "points => points.filter(p => getComputedStyle(p).display !== 'none' && p.offsetWidth > 0).length"
            )
            assert dots == 0  # no hover point: the NaN series' one was drawn at the plot's corner
        texts = legend.locator(".u-series").evaluate_all("rows => rows.map(r => r.getBoundingClientRect().top)")
        assert len(set(round(top) for top in texts)) == 1, texts  # every legend entry on one line
        top = chart.locator(".u-over").first.evaluate("over => parseFloat(getComputedStyle(over).top)")
        assert top >= 10  # room above the plot area for the top tick's label (it was cut in half at 0)
        assert not errors, errors
        page.close()
