"""The guided first visit and the views that teach, in a real browser: each step's sentence against what is drawn.

The tour is clicked through in Debian's chromium as a newcomer would, and at each step the page alone is read (its
texts, its legend, its pixels through the page's own camera, tests/page_reading.py): the invariants every view
keeps (step and slider agree, the highlighted tip where the readout puts it, every legend colour drawn), and what
the step's sentence claims. Noise it, again from the same x_T and the schedule plot are checked the same way.
"""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
from page_reading import blobs, near_color, panel_text, planar_target, project, readout, red_mask, slider_t
from test_browser_viz_invariants import Page, invariants
from viz_helpers import (
    BROWSER_TIMEOUT,
    NO_FADE_CSS,
    canvas_box,
    open_page_collecting_errors,
    read_png,
    running_app,
    settle,
    shipped_solver_or_skip,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow]

MEDIAN = re.compile(r"median of K = (\d+): ([\d.]+) now, ([\d.]+) at t = 0")
REACHED = 0.05  # bone lengths: a tip this near the target "reaches" it (the models' median is under 0.01)
ESTIMATE = (150, 80, 200)  # x̂0's purple (ikdp_viz.style.ESTIMATE)


def shipped_folder():
    from ikdp.shipped import shipped_checkpoint

    return shipped_checkpoint("ikdp_n4").parent


def wait_for_text(page, pattern: str) -> str:
    """The panel's text once it shows `pattern` (a step's heading, a readout): the page is read, never the app."""
    deadline = time.monotonic() + BROWSER_TIMEOUT
    while time.monotonic() < deadline:
        text = panel_text(page)
        if re.search(pattern, text):
            return text
        time.sleep(0.2)
    raise AssertionError(f"the page never showed {pattern!r}: {panel_text(page)[:600]!r}")


def open_still(ui: Page, pattern: str) -> str:
    """Wait for the page to say `pattern` and the app's view to be applied and drawn; then the page's text."""
    wait_for_text(ui.page, pattern)
    assert ui.app.tour.applied.wait(BROWSER_TIMEOUT) or ui.app.tour.index is None
    ui.still()
    return panel_text(ui.page)


def pixels_per_unit(page, ui: Page, text: str) -> tuple[np.ndarray, float]:
    """The target's page pixel and the pixels one bone length spans, through the page's camera."""
    target = planar_target(text)
    centre, one = project(ui.camera(), canvas_box(page), [np.append(target, 0.0), np.append(target + [1, 0], 0.0)])
    return centre, float(np.linalg.norm(one - centre))


def checked(ui: Page, label: str) -> bool:
    return ui.control(label).first.is_checked()


def test_each_tour_step_holds_what_its_sentence_says(browser, tmp_path):
    solver = shipped_solver_or_skip("ikdp_n4")
    shipped_solver_or_skip("ikdp_n2")
    with running_app(solver, animation_seconds=1.0, checkpoint_folder=shipped_folder(), tour=True) as app:
        page, errors = open_page_collecting_errors(browser, app, height=1000)
        page.add_style_tag(content=NO_FADE_CSS)
        ui = Page(app, page, errors, tmp_path)

        def step(number: int, title: str) -> str:
            if number > 1:
                page.get_by_role("button", name="Next", exact=True).click()
            text = open_still(ui, rf"{number} of 6 · {re.escape(title)}")
            page.screenshot(path=str(tmp_path / f"step{number}.png"))
            problems, _ = invariants(ui, robot=False)
            assert not problems, f"step {number}: {problems}"
            return text

        # 1: noise becomes a pose, trail off; played to t = 0, where every tip reaches the cross
        text = step(1, "Noise becomes a pose")
        read = readout(text)
        assert not checked(ui, "show trail") and read.t == 0 and slider_t(page) == 0
        assert not any(line.startswith("trail") for line in legend_texts(page))
        median = MEDIAN.search(text)
        assert int(median[1]) == 16 and float(median[3]) < REACHED

        # 2: x̂0 at t = 50 reaches nearer the target than the state it came from
        text = step(2, "x̂0, the network's guess")
        read = readout(text)
        assert read.t == 50 and checked(ui, "show x̂0")
        image = read_png(page.screenshot())
        centre, per_unit = pixels_per_unit(page, ui, text)
        purple = np.argwhere(near_color(image, ESTIMATE, 40))  # (P, 2) rows, cols of the drawn x̂0
        assert len(purple) > 20, "no x̂0 drawn"
        nearest = float(np.min(np.hypot(purple[:, 1] - centre[0], purple[:, 0] - centre[1])))
        assert nearest < read.error_now * per_unit, (nearest, read.error_now * per_unit)

        # 3: the chart's story: near 1 at t = T, reached at t = 0
        text = step(3, "The error chart")
        read = readout(text)
        assert read.t == 0 and read.error_now < REACHED and checked(ui, "show trail")
        ui.type_number("timestep t", 80)
        noisy = readout(wait_for_text(page, r"Step 0 of 80 \(t = 80\)"))
        assert noisy.error_now > 10 * read.error_now and noisy.error_final == read.error_final

        # 4: one target, 64 answers, all at the target
        text = step(4, "One target, many answers")
        median = MEDIAN.search(text)
        assert readout(text).samples == 64 and int(median[1]) == 64 and float(median[3]) < REACHED

        # 5: the 2-link arm, its two branches named and drawn as two red crosses beside the target's
        text = step(5, "Two branches: elbow up, elbow down")
        assert "A 2-link planar arm" in text and checked(ui, "joint space view")
        said = [line for line in legend_texts(page) if line.startswith("joint space: the target's two exact")]
        assert said and "elbow up and elbow down" in said[0]
        np.testing.assert_allclose(planar_target(text), (1.2, 0.8), atol=1e-3)
        x, y, width, height = (int(value) for value in canvas_box(page))
        canvas = read_png(page.screenshot())[y : y + height, x : x + width]
        assert len(blobs(red_mask(canvas), min_pixels=20)) >= 3  # the target's cross and the two solutions

        # 6: DDPM beside DDIM from one x_T; again: DDPM lands elsewhere, DDIM on the same poses
        text = step(6, "Samplers: stochastic and deterministic")
        assert "beside, titled: ddim from the same x_T" in legend_texts(page)
        ui.choose("highlight", "1")  # one sample followed on both sides ("best" may be another after a rerun)
        wait_for_text(page, r"Tip error, sample 1 of 16")
        ui.still()
        before = read_png(page.screenshot(path=str(tmp_path / "again_before.png")))
        page.get_by_role("button", name="Again from the same x_T").click()
        text = wait_for_text(page, r"Again from the same x_T\*?\*?, run 2")
        ui.still()
        text = panel_text(page)
        assert "ddpm landed elsewhere" in text and "beside it, ddim landed on the same poses" in text
        after = read_png(page.screenshot(path=str(tmp_path / "again_after.png")))
        compare_side = slice(x, x + width // 3)  # the compared sampler's workspace, left of the main one
        main_side = slice(x + width // 2, x + width)
        same, moved = (
            changed_pixels(before, after, compare_side, y, height),
            changed_pixels(before, after, main_side, y, height),
        )
        assert same < 20 and moved > 200, (same, moved)  # DDIM's followed arm drawn in place; DDPM's moved

        page.get_by_role("button", name="Leave the tour").click()
        text = open_still(ui, "Take the tour")
        assert "A 4-link planar arm" in text and checked(ui, "show trail")
        problems, _ = invariants(ui, robot=False)
        assert not problems, f"after the tour: {problems}"
        assert not [error for error in errors if "pageerror" in error], errors
        page.close()


def legend_texts(page) -> list[str]:
    from page_reading import legend

    return [entry.text for entry in legend(page)]


def changed_pixels(before: np.ndarray, after: np.ndarray, columns: slice, top: int, height: int) -> int:
    """Pixels of the followed arm (its dark blue) drawn in one picture and nowhere within 2 px in the other: an arm
    redrawn in place differs only in its anti-aliasing, one that moved by far more. (The grey arms, overlapping,
    change their anti-aliasing by a few hundred pixels when redrawn.)"""
    from scipy import ndimage

    rows = slice(top, top + height)
    drawn = []
    for picture in (before, after):
        r, g, b = (picture[rows, columns, channel].astype(int) for channel in range(3))
        drawn.append((b > 150) & (r < 90) & (g < 150))
    near = [ndimage.binary_dilation(mask, iterations=2) for mask in drawn]
    return int((drawn[1] & ~near[0]).sum() + (drawn[0] & ~near[1]).sum())


def test_noise_it_and_the_schedule_plot_follow_the_slider(browser, tmp_path):
    solver = shipped_solver_or_skip("ikdp_n4")
    with running_app(solver, animation_seconds=1.0) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app, height=1400)
        page.add_style_tag(content=NO_FADE_CSS)
        ui = Page(app, page, errors, tmp_path)
        ui.still()
        clean = readout(panel_text(page))
        page.get_by_role("button", name="Noise it (forward process)").click()
        text = wait_for_text(page, r"Step 0 of 80 \(t = 80\)[\s\S]*forward process \(noise it\)")
        ui.still()
        text = panel_text(page)
        noised = readout(text)
        assert slider_t(page) == 80 and noised.error_final == pytest.approx(clean.error_now, abs=1e-4)
        assert "Noise it: the final poses mixed with one noise" in text and not trail_listed(page)
        assert noised.error_now > 10 * clean.error_now  # at t = T the poses are noise, far from the target
        problems, _ = invariants(ui, robot=False)  # the noised tip drawn where the readout puts it
        assert not problems, problems
        plot = page.locator(".uplot", has_text="the noise schedule").first
        plot.scroll_into_view_if_needed()
        assert "σ(t) noise" in plot.inner_text() and "sampler's steps" in plot.inner_text()
        at_noise = now_dot(page, plot)
        ui.type_number("timestep t", 0)
        wait_for_text(page, r"Step 80 of 80 \(t = 0\)")
        ui.still()
        at_pose = now_dot(page, plot)
        box = plot.locator(".u-over").first.bounding_box()
        assert at_noise[0] - at_pose[0] > 0.8 * box["width"]  # the orange "now" went from t = T (right) to 0 (left)
        assert at_noise[1] < at_pose[1]  # and from sigma near 1 (top) to 0 (bottom)
        page.get_by_text("Words", exact=True).first.click()  # folded at the start: the glossary opens
        words = wait_for_text(page, r"ᾱ_t how much of the pose is left")
        for term in ("x̂0", "σ", "ODE", "DPM-Solver++", "DLS", "FiLM", "cossin", "heading", "p95", "prior"):
            assert re.search(rf"(^|\n){re.escape(term)} \S", words), f"the Words folder defines no {term!r}"
        assert not [error for error in errors if "pageerror" in error], errors
        page.close()


def now_dot(page, plot) -> np.ndarray:
    """The page pixel of the schedule plot's orange "now" dot: in its plotting area (its legend has an orange dot too),
    with a margin for a dot at the area's edge."""
    box = plot.locator(".u-over").first.bounding_box()
    image = read_png(page.screenshot())
    x, y = int(box["x"]) - 8, int(box["y"]) - 8
    region = image[y : y + int(box["height"]) + 16, x : x + int(box["width"]) + 16]
    r, g, b = (region[..., channel].astype(int) for channel in range(3))
    found = blobs((r > 200) & (g > 90) & (g < 160) & (b < 80), min_pixels=10)
    assert found, "no orange dot on the schedule plot"
    centre, _ = max(found, key=lambda blob: blob[1])
    return centre + [x, y]


def trail_listed(page) -> bool:
    """The legend lists a trail (it lists each layer only while drawn)."""
    return any(line.startswith("trail") for line in legend_texts(page))
