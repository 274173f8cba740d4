"""The panel's legend: one line per colour in the scene, its swatch drawn in that colour (HTML, no viser here).

Each arm kind lists what its scene draws (`legend_entries`, planar_kind.py and chain_kind.py); this file only turns
the list into the small HTML block viser's `gui.add_html` shows.
"""

from __future__ import annotations

from dataclasses import dataclass
from html import escape


@dataclass(frozen=True)
class Swatch:
    """How an entry looks: a line, a dot or a cross of one colour, or a line from `faint` to `color` (a ramp)."""

    color: tuple[int, int, int]
    shape: str = "line"  # line, dot or cross
    faint: tuple[int, int, int] | None = None  # a ramp from this colour (t = T) to `color` (t = 0)


@dataclass(frozen=True)
class Entry:
    swatch: Swatch
    text: str  # what the colour means, plain text
    flat: bool = False  # the flat picture of a solve (export.py's PNG) draws it too, so its legend lists it


def css(color: tuple[int, int, int]) -> str:
    if len(color) != 3 or not all(0 <= int(channel) <= 255 for channel in color):
        raise ValueError(f"color: expected three channels 0..255, got {color!r}")
    return "rgb({}, {}, {})".format(*(int(channel) for channel in color))


def swatch_html(swatch: Swatch) -> str:
    if swatch.shape not in {"line", "dot", "cross"}:
        raise ValueError(f"swatch.shape: expected line, dot or cross, got {swatch.shape!r}")
    box = "display:inline-block;vertical-align:middle;margin-right:6px;"
    if swatch.shape == "dot":  # one marker; with `faint`, its two halves the colours it takes at t = T and t = 0
        fill = css(swatch.color)
        if swatch.faint is not None:
            fill = f"linear-gradient(to right, {css(swatch.faint)} 50%, {css(swatch.color)} 50%)"
        return f'<span style="{box}width:10px;height:10px;border-radius:50%;background:{fill}"></span>'
    if swatch.shape == "cross":
        return f'<span style="{box}width:10px;text-align:center;font-weight:700;color:{css(swatch.color)}">✕</span>'
    fill = css(swatch.color)
    if swatch.faint is not None:
        fill = f"linear-gradient(to right, {css(swatch.faint)}, {css(swatch.color)})"
    return f'<span style="{box}width:22px;height:4px;border-radius:2px;background:{fill}"></span>'


def legend_html(entries: list[Entry]) -> str:
    """One line per entry, swatch then text, in the panel's small font."""
    lines = [f'<div style="margin:1px 0">{swatch_html(entry.swatch)}{escape(entry.text)}</div>' for entry in entries]
    return '<div style="font-size:0.8em;line-height:1.45">' + "".join(lines) + "</div>"
