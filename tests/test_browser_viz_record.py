"""A shared denoising opens from disk in chromium, with no server, and shows the arm (ikdp_viz/record.py)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from viz_helpers import BROWSER_TIMEOUT, NO_FADE_CSS, read_png, running_app, settle

import ikdp

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def blue_pixels(image: np.ndarray) -> int:
    """Pixels of the highlighted arm's dark blue (ACCENT_DARK, 20 90 210, shaded or not)."""
    red, green, blue = (image[..., channel].astype(int) for channel in range(3))
    return int(((blue > 150) & (red < 80) & (green < 150)).sum())


def red_pixels(image: np.ndarray) -> int:
    """Pixels of the target's red cross."""
    red, green, blue = (image[..., channel].astype(int) for channel in range(3))
    return int(((red > 170) & (green < 90) & (blue < 90)).sum())


def test_the_shared_html_plays_from_disk_with_no_server_and_shows_the_arm(browser, tiny_checkpoint, tmp_path):
    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0, target=(1.2, 0.6)) as app:
        settle(app)
        name, page_text = app.share()
    path = tmp_path / name
    path.write_text(page_text, encoding="utf-8")  # the server is stopped: the file is all there is
    page = browser.new_page(viewport={"width": 1000, "height": 700})
    fetched: list[str] = []
    page.on("request", lambda request: fetched.append(request.url))
    try:
        page.goto(path.as_uri())
        page.add_style_tag(content=NO_FADE_CSS)
        page.locator("canvas").first.wait_for(timeout=BROWSER_TIMEOUT * 1000)
        box = page.locator("canvas").first.bounding_box()  # the scene alone: the playback bar's slider is blue too
        rows = slice(int(box["y"]), int(box["y"] + box["height"]))
        columns = slice(int(box["x"]), int(box["x"] + box["width"]))
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while True:
            image = read_png(page.screenshot())[rows, columns]
            if (blue_pixels(image) > 30 and red_pixels(image) > 30) or time.monotonic() > deadline:
                break
            time.sleep(0.5)
        assert blue_pixels(image) > 30, "the highlighted arm never showed"
        assert red_pixels(image) > 30, "the target's cross never showed"
        assert page.locator(".mantine-Slider-root").count() >= 1  # the playback bar's time slider, to scrub
        assert all(url.split(":", 1)[0] in {"file", "data", "blob"} for url in fetched), fetched  # no server
    finally:
        page.close()


def test_the_share_button_downloads_the_page_to_the_tab_that_clicked(browser, tiny_checkpoint, tmp_path):
    from viz_helpers import open_page_collecting_errors

    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0, target=(1.2, 0.6)) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app, height=1600)
        try:
            with page.expect_download(timeout=BROWSER_TIMEOUT * 1000) as download:
                page.get_by_role("button", name="Share this denoising (HTML)").click()
            saved = tmp_path / download.value.suggested_filename
            download.value.save_as(saved)
            assert saved.name.startswith("ikdp_ddpm_K16_seed0_") and saved.suffix == ".html"
            text = saved.read_text(encoding="utf-8")
            assert "window.__VISER_EMBED_DATA__=" in text and len(text) > 100_000
            assert app.panel.learn.share.label == "Share this denoising (HTML)" and not app.panel.learn.share.disabled
            assert not errors, errors[:3]
        finally:
            page.close()
