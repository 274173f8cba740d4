"""A window taller than wide: the planar reach circle is drawn whole, inside the canvas, at both sides."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from viz_helpers import BROWSER_TIMEOUT, canvas_box, read_png, running_app, settle

import ikdp

pytestmark = [pytest.mark.browser, pytest.mark.slow]

GREY = (140, 200)  # the reach circle's grey (150) as the page draws its thin line, blended with the white


def grey_columns(image: np.ndarray, row: int, box) -> np.ndarray:
    """Canvas columns of row `row` (page pixels) drawn in the reach circle's grey (neutral, darker than the grid)."""
    x, _, width, _ = (int(value) for value in box)
    pixels = image[row - 1 : row + 2, x : x + width, :3].astype(int)
    neutral = pixels.max(axis=-1) - pixels.min(axis=-1) <= 6
    grey = (neutral & (pixels.min(axis=-1) >= GREY[0]) & (pixels.max(axis=-1) <= GREY[1])).any(axis=0)
    return x + np.flatnonzero(grey)


def test_a_tall_window_shows_the_whole_reach_circle(browser, tiny_checkpoint):
    solver = ikdp.load(tiny_checkpoint)
    outer = solver.reach[1]
    with running_app(solver, target=(0.5 * outer, 0.4 * outer), animation_seconds=0.0) as app:
        settle(app)
        page = browser.new_page(viewport={"width": 1280, "height": 1700})
        page.goto(f"http://127.0.0.1:{app.server.get_port()}")
        page.get_by_text("Connected", exact=True).wait_for(timeout=BROWSER_TIMEOUT * 1000)
        box = canvas_box(page)
        row = int(round(box[1] + box[3] / 2))  # the camera looks down at the base: the circle's widest row
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while True:
            image = read_png(page.screenshot())
            columns = grey_columns(image, row, box)
            if len(columns) >= 2 and columns[-1] - columns[0] > 0.6 * box[2] or time.monotonic() > deadline:
                break
            time.sleep(0.3)
        if os.environ.get("IKDP_SHOTS"):
            page.screenshot(path=os.path.join(os.environ["IKDP_SHOTS"], "tall_window.png"))
        page.close()
    assert len(columns) >= 2, "no part of the reach circle is drawn across the base's row"
    left, right = int(columns[0]), int(columns[-1])
    middle = box[0] + box[2] / 2
    # both sides of the circle are drawn, inside the canvas and clear of its edges, about the base at the middle
    assert left > box[0] + 5 and right < box[0] + box[2] - 5, (left, right, box)
    assert abs((left + right) / 2 - middle) < 0.05 * box[2], (left, right, middle)
    # the circle, not the light trails inside it: at the default framing it spans three quarters of the canvas
    assert right - left > 0.6 * box[2], (left, right, box)
