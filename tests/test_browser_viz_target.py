"""The target's red cross and gizmo in a real browser: the cross drawn where the tips land, over the arms, and
on the clamped point while a drag goes past the workspace boundary (as the panel's "clamped" says); the gizmo
dragged anywhere in the reach about the base."""

from __future__ import annotations

import time

import numpy as np
import pytest
from viz_helpers import (
    BROWSER_TIMEOUT,
    NO_FADE_CSS,
    canvas_box,
    open_page_collecting_errors,
    project,
    read_png,
    running_app,
    settle,
)

import ikdp
from ikdp_viz.camera import over_the_point

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def red_mask(image: np.ndarray) -> np.ndarray:
    pixels = image.astype(int)
    return (pixels[..., 0] > 170) & (pixels[..., 1] < 90) & (pixels[..., 2] < 90)


def cross_centre(image: np.ndarray, near: np.ndarray, radius: float) -> tuple[np.ndarray | None, int]:
    """Centroid (u, v) of the red pixels within `radius` px of `near`, and how many there are."""
    rows, cols = np.nonzero(red_mask(image))
    close = np.hypot(cols - near[0], rows - near[1]) < radius
    if close.sum() == 0:
        return None, 0
    return np.array([cols[close].mean(), rows[close].mean()]), int(close.sum())


def wait_for_cross(page, near: np.ndarray, radius: float, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """The page's picture once a red cross is drawn within `tolerance` px of `near` (or at the timeout); its centre."""
    deadline = time.monotonic() + BROWSER_TIMEOUT
    while True:
        image = read_png(page.screenshot())
        centre, count = cross_centre(image, near, radius)
        done = centre is not None and count > 30 and np.linalg.norm(centre - near) <= tolerance
        if done or time.monotonic() > deadline:
            return image, centre
        time.sleep(0.2)


def test_the_cross_is_drawn_on_the_target_over_the_arms_and_on_the_clamped_point(browser, tiny_checkpoint):
    solver = ikdp.load(tiny_checkpoint)
    outer = solver.reach[1]
    target = (0.6 * outer, 0.55 * outer)  # far from the camera's axis: a lifted cross showed 15-25 px off
    with running_app(solver, target=target, animation_seconds=0.0) as app:
        app.panel.refine.value = True  # the refined tips land on the target: an arm's end under the cross
        settle(app)
        page, errors = open_page_collecting_errors(browser, app)
        page.add_style_tag(content=NO_FADE_CSS)
        box = canvas_box(page)
        pixels_per_unit = float(
            np.linalg.norm(project(app, box, np.array([1.0, 0.0])) - project(app, box, np.zeros(2)))
        )
        arm = pixels_per_unit * app.writer.view.sizes.cross  # the cross's half size on screen
        app.gizmo.visible = False  # its red x arrow would count as the cross
        expected = project(app, box, app.target)  # the target on the plane, where the tips land
        image, centre = wait_for_cross(page, expected, 1.6 * arm, tolerance=2.0)
        assert centre is not None and np.linalg.norm(centre - expected) <= 2.0, (centre, expected)
        u, v = np.rint(expected).astype(int)
        assert red_mask(image[v - 1 : v + 2, u - 1 : u + 2]).all()  # over the refined tips, not under them

        app.gizmo.visible = True
        camera = app.server.initial_camera.position
        grip = project(app, box, app.target + [0.6 * app.gizmo.scale, 0.0])  # on the gizmo's x arrow
        u, v = np.rint(grip).astype(int)
        hidden = image[v - 3 : v + 4, u - 3 : u + 4].astype(int)  # the arrow's place while the gizmo was hidden
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while time.monotonic() < deadline:  # until the arrow is drawn again, to be grabbed
            shown = read_png(page.screenshot())[v - 3 : v + 4, u - 3 : u + 4].astype(int)
            if np.abs(shown - hidden).max() > 60:
                break
            time.sleep(0.1)
        beyond = grip + [(outer + 1.0 - app.target[0]) * pixels_per_unit, 0.0]  # past the boundary
        page.mouse.move(*grip)
        page.mouse.down()
        try:
            for step in np.linspace(0, 1, 15)[1:]:
                page.mouse.move(*(grip + step * (beyond - grip)))
                time.sleep(0.03)
            deadline = time.monotonic() + BROWSER_TIMEOUT
            while np.hypot(*app.target) < outer - 1e-6 and time.monotonic() < deadline:
                time.sleep(0.05)
            settle(app)
            clamped = app.target.copy()
            assert np.hypot(*clamped) == pytest.approx(outer) and "Clamped" in app.panel.target_text.content
            height = app.cross.position[2]  # the cross is its own node, placed by the server on the clamped point
            np.testing.assert_allclose(app.cross.position, over_the_point(clamped, height, camera), atol=1e-9)
        finally:
            page.mouse.up()
        settle(app)
        app.gizmo.visible = False  # its arrows, drawn over everything, hide part of the cross
        expected = project(app, box, clamped)
        image, centre = wait_for_cross(page, expected, 1.6 * arm, tolerance=2.0)
        assert centre is not None and np.linalg.norm(centre - expected) <= 2.0, (centre, expected)
        base = project(app, box, np.zeros(2))
        assert np.linalg.norm(centre - base) <= outer * pixels_per_unit + 2.0  # on the circle, not beyond
        assert not any("pageerror" in error for error in errors), errors
        page.close()


def wait_for_x_arrow(page, app, box) -> None:
    """Wait until the page has drawn the server's last move of the target (its red cross there: the gizmo moves in
    the same update), so a drag grabs the gizmo where the server put it."""
    expected = project(app, box, app.target)
    _, centre = wait_for_cross(page, expected, 40.0, tolerance=8.0)
    assert centre is not None and np.linalg.norm(centre - expected) <= 8.0, (centre, expected, app.target)
    time.sleep(0.3)


def drag_x_arrow(page, app, box, pixels_per_unit: float, to_x: float) -> None:
    """Drag the gizmo's x arrow in the page so that, unlimited, the target would go to x = `to_x`; the mouse is
    left down (the caller releases it)."""
    grip = project(app, box, app.target + [0.6 * app.gizmo.scale, 0.0])
    end = grip + [(to_x - app.target[0]) * pixels_per_unit, 0.0]
    page.mouse.move(*grip)
    page.mouse.down()
    for step in np.linspace(0, 1, 20)[1:]:
        page.mouse.move(*(grip + step * (end - grip)))
        time.sleep(0.03)
    time.sleep(0.5)  # the page's last drag message


def test_the_gizmo_drags_across_the_whole_reach_around_the_base_not_around_the_first_target(browser, tiny_checkpoint):
    solver = ikdp.load(tiny_checkpoint)
    outer = solver.reach[1]
    with running_app(solver, target=(0.55 * outer, 0.3 * outer), animation_seconds=0.0) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app)
        page.add_style_tag(content=NO_FADE_CSS)
        box = canvas_box(page)
        pixels_per_unit = float(
            np.linalg.norm(project(app, box, np.array([1.0, 0.0])) - project(app, box, np.zeros(2)))
        )
        wait_for_x_arrow(page, app, box)
        # across the base to x = -0.85 reach, inside the circle: limits about the first target stopped at -0.45
        drag_x_arrow(page, app, box, pixels_per_unit, -0.85 * outer)
        page.mouse.up()
        settle(app)
        assert app.gizmo.position[0] == pytest.approx(-0.85 * outer, abs=0.03 * outer)
        assert app.target[0] == pytest.approx(-0.85 * outer, abs=0.03 * outer)

        # after the server moves it (a typed target), the limits are still the reach about the base
        app.move_target(np.array([-0.5 * outer, 0.3 * outer]))
        settle(app)
        wait_for_x_arrow(page, app, box)  # the page has drawn the gizmo there (seconds on a loaded machine)
        time.sleep(0.5)
        drag_x_arrow(page, app, box, pixels_per_unit, -1.5 * outer)
        try:  # past the circle (limits left about the first drawing stopped it at -0.65 reach, inside)
            assert app.gizmo.position[0] < -0.9 * outer
        finally:
            page.mouse.up()
        settle(app)
        assert np.hypot(*app.target) == pytest.approx(outer) and "Clamped" in app.panel.target_text.content
        assert not any("pageerror" in error for error in errors), errors
        page.close()


def test_a_new_tab_sees_the_denoising_from_pure_noise(browser, tiny_checkpoint):
    """The page's first drawn frame shows the start of the denoising, not its end: play waits for the page to draw."""
    solver = ikdp.load(tiny_checkpoint)
    outer = solver.reach[1]
    target = (0.6 * outer, 0.55 * outer)
    with running_app(solver, target=target, animation_seconds=1.0, wait_for_tab=True) as app:
        assert app.wait_until_still(60) and app.state == 0 and not app.playing  # pure noise, waiting for a tab
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page.goto(f"http://127.0.0.1:{app.server.get_port()}")
        last = app.solved.view.num_states - 1
        first_drawn = None
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while first_drawn is None and time.monotonic() < deadline:
            image = read_png(page.screenshot())
            if red_mask(image).sum() > 30:  # the scene is drawn (the red cross and the gizmo's red arrow)
                first_drawn = app.state
        assert first_drawn is not None, "the page never drew the scene"
        assert first_drawn <= 0.1 * last, (first_drawn, last)  # the start of the denoising is seen
        while app.state < last and time.monotonic() < deadline:  # the page's answer may come after the screenshot
            time.sleep(0.1)
        settle(app)
        assert app.state == last  # and it played to the end
        page.close()
