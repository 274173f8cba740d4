"""The README's pictures are of the viewer as it is (issue 25, finding 15: docs/screenshot.png showed a chart that
no longer existed).

A picture made by `python -m ikdp_viz.screenshot` carries a stamp of its panel (the controls' labels, the chart's
title, axes and series, the legend: screenshot.panel_stamp). Here the command the docs give for the README's
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
README_VIEWER_PICTURE = "docs/screenshot.png"


def readme_images() -> list[str]:
    return re.findall(r"!\[[^\]]*\]\(([^)\s]+)\)", (REPO / "README.md").read_text(encoding="utf-8"))


def documented_command(picture: str) -> list[str]:
    """The arguments docs/VIZ.md gives to `python -m ikdp_viz.screenshot` for `picture`."""
    text = (REPO / "docs" / "VIZ.md").read_text(encoding="utf-8")
    commands = re.findall(r"`python -m ikdp_viz\.screenshot ([^`]*)`", text)
    found = [shlex.split(command) for command in commands if f"--output {picture}" in command]
    assert found, f"docs/VIZ.md gives no `python -m ikdp_viz.screenshot ... --output {picture}` command"
    return found[0]


def documented_gallery_commands() -> list[list[str]]:
    """Every `$S ...` line of docs/VIZ.md's code blocks, where S is the screenshot module (lines joined at `\\`)."""
    text = (REPO / "docs" / "VIZ.md").read_text(encoding="utf-8").replace("\\\n", " ")
    return [shlex.split(line)[1:] for line in text.splitlines() if line.startswith("$S ")]


def test_the_readme_s_pictures_exist_and_its_viewer_picture_is_documented():
    images = readme_images()
    assert README_VIEWER_PICTURE in images, images
    assert [image for image in images if not (REPO / image).is_file()] == []
    documented_command(README_VIEWER_PICTURE)


@pytest.mark.parametrize("arguments", documented_gallery_commands(), ids=lambda arguments: arguments[1])
def test_every_documented_screenshot_command_parses(arguments):
    tyro.cli(ScreenshotConfig, args=arguments)  # an option that no longer exists exits with its usage


def test_the_readme_s_viewer_picture_shows_the_panel_of_today():
    stamp = read_stamp(REPO / README_VIEWER_PICTURE)
    arguments = documented_command(README_VIEWER_PICTURE)
    retake = f"retake it: python -m ikdp_viz.screenshot {shlex.join(arguments)}"
    assert stamp is not None, f"{README_VIEWER_PICTURE} has no panel stamp (taken before stamps); {retake}"
    server, app = configured_app(tyro.cli(ScreenshotConfig, args=arguments))
    try:
        now = panel_stamp(app.panel)
    finally:
        app.close()
        server.stop()
    for part in ("chart", "controls", "legend"):
        assert stamp[part] == now[part], f"{README_VIEWER_PICTURE} shows another {part} than the viewer; {retake}"
