"""The docs' pictures are of the viewer as it is (a picture once showed a chart the viewer no longer had).

A picture made by `python -m ikdp_viz.screenshot` carries a stamp of its panel (the controls' labels, the chart's
title, axes and series, the legend: screenshot.panel_stamp). Here the command docs/viewer.md gives for its first
picture is parsed by the screenshot module's own parser (an option that no longer exists fails), the viewer is
built and solved as that command does (no browser), and its stamp must equal the picture's.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
import tyro

from ikdp_viz.screenshot import ScreenshotConfig, configured_app, panel_stamp, read_stamp

REPO = Path(__file__).resolve().parents[1]
VIEWER_PAGE = REPO / "docs" / "viewer.md"
VIEWER_PICTURE = "docs/screenshot.png"  # the viewer page's first picture
README_ANIMATION = "docs/assets/viewer.webp"


def images(page: Path) -> list[str]:
    """The pictures a Markdown page shows, as paths from the repository's root."""
    found = re.findall(r"!\[[^\]]*\]\(([^)\s]+)\)", page.read_text(encoding="utf-8"))
    return [str((page.parent / image).resolve().relative_to(REPO)) for image in found]


def documented_command(picture: str) -> list[str]:
    """The arguments docs/viewer.md gives to `python -m ikdp_viz.screenshot` for `picture`."""
    text = VIEWER_PAGE.read_text(encoding="utf-8")
    commands = re.findall(r"`python -m ikdp_viz\.screenshot ([^`]*)`", text)
    found = [shlex.split(command) for command in commands if f"--output {picture}" in command]
    assert found, f"docs/viewer.md gives no `python -m ikdp_viz.screenshot ... --output {picture}` command"
    return found[0]


def documented_gallery_commands() -> list[list[str]]:
    """Every `$S ...` line of docs/viewer.md's code blocks, where S is the screenshot module (lines joined at `\\`)."""
    text = VIEWER_PAGE.read_text(encoding="utf-8").replace("\\\n", " ")
    return [shlex.split(line)[1:] for line in text.splitlines() if line.startswith("$S ")]


def test_the_readme_shows_the_viewer_animated_and_every_picture_exists():
    shown = images(REPO / "README.md")
    assert README_ANIMATION in shown, shown
    assert [image for image in shown if not (REPO / image).is_file()] == []


def test_the_viewer_page_s_pictures_exist_and_each_screenshot_has_its_command():
    shown = images(VIEWER_PAGE)
    assert VIEWER_PICTURE in shown, shown
    assert [image for image in shown if not (REPO / image).is_file()] == []
    documented_command(VIEWER_PICTURE)
    made = {arguments[arguments.index("--output") + 1] for arguments in documented_gallery_commands()}
    gallery = [image for image in shown if image.startswith("docs/gallery/")]
    assert [image for image in gallery if image not in made] == []


@pytest.mark.parametrize("arguments", documented_gallery_commands(), ids=lambda arguments: arguments[1])
def test_every_documented_screenshot_command_parses(arguments):
    tyro.cli(ScreenshotConfig, args=arguments)  # an option that no longer exists exits with its usage


def test_the_viewer_page_s_first_picture_shows_the_panel_of_today():
    stamp = read_stamp(REPO / VIEWER_PICTURE)
    arguments = documented_command(VIEWER_PICTURE)
    retake = f"retake it: python -m ikdp_viz.screenshot {shlex.join(arguments)}"
    assert stamp is not None, f"{VIEWER_PICTURE} has no panel stamp (taken before stamps); {retake}"
    server, app = configured_app(tyro.cli(ScreenshotConfig, args=arguments))
    try:
        now = panel_stamp(app.panel)
    finally:
        app.close()
        server.stop()
    for part in ("chart", "controls", "legend"):
        assert stamp[part] == now[part], f"{VIEWER_PICTURE} shows another {part} than the viewer; {retake}"
