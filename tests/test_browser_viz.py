"""The viewer in a real browser: Debian's chromium through Playwright, software WebGL.

Pixels are checked where the drawn arm projects through the app's initial
top-down camera (tests/viz_helpers.project). Every wait polls for a condition
with a generous timeout; nothing depends on how fast this machine is.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from viz_helpers import (
    BROWSER_TIMEOUT,
    NO_FADE_CSS,
    canvas_box,
    dark_fraction,
    drag_gizmo,
    project,
    read_png,
    running_app,
    settle,
)

import ikdp

pytestmark = [pytest.mark.browser, pytest.mark.slow]

TARGET = (1.4, 0.9)


class Viewer:
    """One app, one page on it, and the page's picture before the arm was first drawn."""

    def __init__(self, app, page, console: list[str]):
        self.app, self.page, self.console = app, page, console
        self.before: np.ndarray | None = None

    def screenshot(self, page=None) -> np.ndarray:
        return read_png((page or self.page).screenshot())

    def final_link_pixels(self) -> np.ndarray:
        """Page pixels of the midpoints of the final pose's dark links, away from the base and the gizmo."""
        return link_pixels(self.app, self.page, self.app.solved.view.joints[-1])

    def wait_for_picture(self, condition, page=None, timeout: float = BROWSER_TIMEOUT) -> np.ndarray:
        deadline = time.monotonic() + timeout
        while True:
            image = self.screenshot(page)
            if condition(image) or time.monotonic() > deadline:
                return image
            time.sleep(0.2)


def open_page(browser, app, console: list[str] | None = None):
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    if console is not None:
        page.on("console", lambda message: console.append(message.text))
        page.on("pageerror", lambda error: console.append(f"pageerror: {error}"))
    page.goto(f"http://127.0.0.1:{app.server.get_port()}")
    page.add_style_tag(content=NO_FADE_CSS)
    page.get_by_text("Connected", exact=True).wait_for(timeout=BROWSER_TIMEOUT * 1000)
    return page


def link_pixels(app, page, joints: np.ndarray) -> np.ndarray:
    """Midpoints of the links of `joints` (K, N+1, 2) not highlighted, clear of the base and the gizmo, as pixels."""
    highlight = app.highlight_index()
    middles = (joints[:, :-1] + joints[:, 1:]) / 2  # (K, N, 2)
    middles = np.delete(middles, highlight, axis=0).reshape(-1, 2)
    unit = float(np.mean(app.solver.lengths))
    clear = (np.linalg.norm(middles, axis=-1) > 0.4 * unit) & (np.linalg.norm(middles - app.target, axis=-1) > unit)
    return project(app, canvas_box(page), middles[clear])


def red_near(image: np.ndarray, pixel: np.ndarray, radius: int = 12) -> bool:
    """The red cross (or the gizmo's red axis) near `pixel`."""
    u, v = np.rint(pixel).astype(int)
    window = image[v - radius : v + radius + 1, u - radius : u + radius + 1].astype(int)
    return bool(((window[..., 0] > 170) & (window[..., 1] < 90) & (window[..., 2] < 90)).any())


@pytest.fixture(scope="module")
def viewer(browser, tiny_checkpoint):
    solver = ikdp.load(tiny_checkpoint)
    with running_app(solver, solve_now=False, target=TARGET, animation_seconds=0.0) as app:
        app.panel.learn.trail_of.value = "all samples"  # every final link dark: what these tests look for
        console: list[str] = []
        page = open_page(browser, app, console)
        viewer = Viewer(app, page, console)
        target_pixel = project(app, canvas_box(page), np.array(TARGET))
        viewer.before = viewer.wait_for_picture(lambda image: red_near(image, target_pixel))  # the static scene is up
        if not red_near(viewer.before, target_pixel):
            # CI's first browser page stayed white three times, through a reload (RenderingBrowser): a new browser
            page.close()
            browser.relaunch()
            page = viewer.page = open_page(browser, app, console)
            viewer.before = viewer.wait_for_picture(lambda image: red_near(image, target_pixel))
        assert red_near(viewer.before, target_pixel), f"the target's red cross never appeared; console: {console}"
        yield viewer
        page.close()


def show_final_pose(viewer) -> np.ndarray:
    """Solve (if nothing is drawn yet), show the final pose, and return the page once it shows it."""
    app = viewer.app
    if app.solved is None:
        app.move_target(TARGET)
    settle(app)
    app.show_state(app.solved.view.num_states - 1)
    pixels = viewer.final_link_pixels()
    assert len(pixels) >= 10
    return viewer.wait_for_picture(lambda image: dark_fraction(image, pixels) >= 0.8)


def test_the_page_connects_with_webgl_and_shows_the_arm_once_drawn(viewer):
    page = viewer.page
    text = page.evaluate("() => document.body.innerText")
    assert "WebGL unavailable" not in text and "Connected" in text
    assert any("WebGL support: true" in line for line in viewer.console), viewer.console
    assert not any("contextCreationFailed: true" in line or "pageerror" in line for line in viewer.console)
    after = show_final_pose(viewer)
    pixels = viewer.final_link_pixels()
    assert dark_fraction(after, pixels) >= 0.8  # dark where the arm's projection falls
    assert dark_fraction(viewer.before, pixels) == 0.0  # and nothing there before the server drew it


def test_the_default_picture_draws_the_highlighted_arm_blue_and_the_others_light(viewer):
    app = viewer.app
    show_final_pose(viewer)
    app.panel.learn.trail_of.value = "highlighted"  # the viewer's default (the paper's figure)
    try:
        others = viewer.final_link_pixels()
        joints = app.solved.view.joints[-1]
        highlight = app.highlight_index()
        middles = (joints[highlight, :-1] + joints[highlight, 1:]) / 2
        middles = middles[np.linalg.norm(middles - app.target, axis=-1) > np.mean(app.solver.lengths)]  # no gizmo
        chosen = project(app, canvas_box(viewer.page), middles)
        assert len(chosen) >= 1

        def blue_at(image, pixel, radius=2) -> bool:
            u, v = np.rint(pixel).astype(int)
            window = image[v - radius : v + radius + 1, u - radius : u + radius + 1, :3].astype(int)
            return bool(((window[..., 2] > 150) & (window[..., 0] < 90)).any())

        image = viewer.wait_for_picture(
            lambda image: dark_fraction(image, others) < 0.2 and all(blue_at(image, pixel) for pixel in chosen)
        )
        assert all(blue_at(image, pixel) for pixel in chosen)  # the followed sample: dark blue
        assert dark_fraction(image, others) < 0.2  # the others: light, no longer near black
    finally:
        app.panel.learn.trail_of.value = "all samples"


def test_moving_the_timestep_slider_in_the_page_changes_the_picture(viewer):
    app, page = viewer.app, viewer.page
    final = show_final_pose(viewer)
    pixels = viewer.final_link_pixels()
    slider = page.locator("[role=slider]").first  # the panel's first slider is the timestep
    assert slider.get_attribute("aria-valuemax") == str(app.solver.timesteps)
    slider.focus()
    page.keyboard.press("End")  # t = T: pure noise
    deadline = time.monotonic() + BROWSER_TIMEOUT
    while app.state != 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert app.state == 0 and app.panel.timestep.value == app.solver.timesteps
    noisy = viewer.wait_for_picture(lambda image: dark_fraction(image, pixels) < 0.3)
    assert dark_fraction(final, pixels) >= 0.8 and dark_fraction(noisy, pixels) < 0.3
    changed = np.abs(noisy.astype(int) - final.astype(int)).max(axis=-1) > 60
    assert changed.mean() > 0.005  # a visible part of the picture changed
    page.keyboard.press("Home")  # back to t = 0
    back = viewer.wait_for_picture(lambda image: dark_fraction(image, pixels) >= 0.8)
    assert app.state == app.solved.view.num_states - 1 and dark_fraction(back, pixels) >= 0.8


def test_dragging_the_gizmo_moves_the_target_and_the_arm_follows(viewer):
    app, page = viewer.app, viewer.page
    show_final_pose(viewer)
    start_target = app.target.copy()
    box = canvas_box(page)
    grip = project(app, box, start_target + [0.6 * app.gizmo.scale, 0.0])  # on the gizmo's x arrow
    page.mouse.move(*grip)
    page.mouse.down()
    for step in range(1, 11):  # 80 px right (and a little down: the x arrow ignores it)
        page.mouse.move(grip[0] + 8 * step, grip[1] + 2 * step)
        time.sleep(0.03)
    page.mouse.up()
    deadline = time.monotonic() + BROWSER_TIMEOUT
    while app.target[0] < start_target[0] + 0.2 and time.monotonic() < deadline:
        time.sleep(0.05)
    settle(app)
    moved = app.target - start_target
    assert moved[0] > 0.2 and abs(moved[1]) < 1e-6  # along x only, as far as the mouse went
    assert np.allclose(app.solved.view.target, app.target)  # the drawn solve is the dragged target's
    assert np.allclose(app.gizmo.position[:2], app.target)
    pixels = viewer.final_link_pixels()
    after = viewer.wait_for_picture(lambda image: dark_fraction(image, pixels) >= 0.8)
    assert dark_fraction(after, pixels) >= 0.8  # the new arm is on screen
    assert red_near(after, project(app, box, app.target))  # so is the cross, at the new target


def test_two_tabs_see_one_scene_and_closing_one_mid_animation_breaks_nothing(viewer, browser):
    app = viewer.app
    show_final_pose(viewer)
    second = open_page(browser, app)
    pixels = viewer.final_link_pixels()
    shown = viewer.wait_for_picture(lambda image: dark_fraction(image, pixels) >= 0.8, page=second)
    assert dark_fraction(shown, pixels) >= 0.8  # the second tab shows the same arm
    app.panel.duration.value = 1.5
    try:
        drag_gizmo(app, -1.0, 1.6, phase="end")  # a move in one go: its solve is animated
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while not app.playing and time.monotonic() < deadline:
            time.sleep(0.01)
        assert app.playing
        second.close()  # mid-animation
        settle(app)
    finally:
        app.panel.duration.value = 0.0
    assert app.state == app.solved.view.num_states - 1 and np.allclose(app.solved.view.target, [-1.0, 1.6])
    pixels = viewer.final_link_pixels()
    after = viewer.wait_for_picture(lambda image: dark_fraction(image, pixels) >= 0.8)
    assert dark_fraction(after, pixels) >= 0.8  # the first tab still follows
    deadline = time.monotonic() + BROWSER_TIMEOUT
    while len(app.server.get_clients()) != 1 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert len(app.server.get_clients()) == 1
    assert not any("pageerror" in line for line in viewer.console)


def test_opening_a_longer_arm_fits_the_open_tabs_view_to_its_reach(viewer, tiny_checkpoint):
    """An N=8 checkpoint opened from the panel used to keep the N=4 camera."""
    from ikdp.shipped import list_shipped
    from ikdp_viz.app import camera_fit

    longer = next((path for path in list_shipped() if path.stem == "ikdp_n8"), None)
    if longer is None:
        pytest.skip("the shipped ikdp_n8 is not there")
    app = viewer.app
    clients = list(app.server.get_clients().values())  # every open tab, this module's page among them
    try:
        assert app.load_checkpoint(longer)
        settle(app)
        expected, _ = camera_fit(app.solver.reach[1])
        deadline = time.monotonic() + BROWSER_TIMEOUT
        fitted = lambda: all(np.allclose(client.camera.position, expected, atol=1e-3) for client in clients)  # noqa: E731
        while not fitted() and time.monotonic() < deadline:
            time.sleep(0.1)  # the pages report their cameras back
        assert fitted(), [client.camera.position for client in clients]
        pixels = link_pixels(app, viewer.page, app.solved.view.joints[-1])
        assert len(pixels) and (pixels >= 0).all() and (pixels[:, 0] <= 1280).all() and (pixels[:, 1] <= 800).all()
    finally:
        assert app.load_checkpoint(tiny_checkpoint)
        settle(app)


def test_the_timestep_slider_and_its_number_box_are_drawn_on_layers_of_their_own(viewer):
    """The panel's style puts them on compositing layers (docs/viewer.md, "Frames in the page"): the page then
    re-rasters two small layers, not the panel around them, with each state a played denoising draws. A viser that
    renamed its slider's classes would lose that without a word; this says so."""
    changes = viewer.page.evaluate(
        """() => { const slider = document.querySelector('[role=slider]');
          const row = slider.closest('.mantine-Slider-root'), box = row && row.parentElement.querySelector(
            '.mantine-NumberInput-root');
          return [row && getComputedStyle(row).willChange, box && getComputedStyle(box).willChange]; }"""
    )
    assert changes == ["transform", "transform"], changes
