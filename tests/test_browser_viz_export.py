"""Export GIF + PNG in a real browser: both files land in the downloads of the tab that clicked,
with progress while the GIF renders and one notification per export, never a pile of links."""

from __future__ import annotations

import time

import numpy as np
import pytest
from viz_helpers import BROWSER_TIMEOUT, open_page_collecting_errors, running_app, settle

import ikdp

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def notification_texts(page) -> list[str]:
    return page.evaluate("() => [...document.querySelectorAll('.mantine-Notification-root')].map(n => n.innerText)")


def test_export_saves_both_files_in_the_tab_that_asked_with_progress_and_no_pile(browser, tiny_checkpoint):
    import imageio.v2 as imageio

    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app)
        other, _ = open_page_collecting_errors(browser, app)  # a second tab, which must get nothing
        downloads, elsewhere = [], []
        page.on("download", lambda download: downloads.append(download))
        other.on("download", lambda download: elsewhere.append(download))
        button = page.get_by_role("button", name="Export GIF + PNG")
        seen: set[str] = set()
        for round_ in range(2):  # twice: the second export's notification replaces the first's
            button.click()
            deadline = time.monotonic() + BROWSER_TIMEOUT
            while len(downloads) < 2 * (round_ + 1) and time.monotonic() < deadline:
                seen.update(text for text in notification_texts(page) if "frame" in text)
                time.sleep(0.05)
        assert len(downloads) == 4 and not elsewhere
        names = [download.suggested_filename for download in downloads]
        stem = f"ikdp_{app.solved.request.sampler}_K{app.solved.view.num_samples}"
        assert names[0].startswith(stem) and names[0].endswith(".gif") and names[1].endswith("_trail.png")
        frames = imageio.mimread(downloads[0].path())
        assert 2 < len(frames) <= 41 and not np.array_equal(frames[0], frames[-1])  # the viewer's clock: fewer noisy
        assert any("rendering the GIF: frame" in text for text in seen)  # progress while it renders
        deadline = time.monotonic() + BROWSER_TIMEOUT
        while not any("Exported" in text for text in notification_texts(page)) and time.monotonic() < deadline:
            time.sleep(0.05)
        texts = [text.replace("\u200b", "") for text in notification_texts(page)]  # the names' wrap points
        ours = [text for text in texts if "Export" in text]
        assert len(ours) == 1 and names[2] in ours[0] and names[3] in ours[0], texts  # one, naming both files
        truncated = page.locator(".mantine-Notification-description").evaluate_all(
            "nodes => nodes.filter(n => n.scrollWidth > n.clientWidth + 1).length"
        )
        assert truncated == 0  # the names wrap, none is cut off
        assert not page.locator(".mantine-Notification-root a[download]").count()  # no links to click
        assert not other.locator(".mantine-Notification-root").filter(has_text="Export").count()
        assert not any("pageerror" in error for error in errors), errors
        other.close()
        page.close()
