"""What a person reads off the viewer's page: the panel's texts, the legend's swatches, the timestep slider, and
coloured marks in the canvas, placed through the page's own camera. Nothing here asks the server's Python state
what it drew; the camera is the one the page reports (viser sends it back as the user sees it)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

STEP = re.compile(r"Step (\d+) of (\d+) \(t = (\d+)\)")
TIP_ERROR = re.compile(r"Tip error, sample (\d+) of (\d+)[^:\n]*: ([\d.]+) now, ([\d.]+) at t = 0")
HAND_ERROR = re.compile(r"Hand error, sample (\d+) of (\d+)[^:\n]*: ([\d.]+) mm(?: / ([\d.]+)°)?[^,\n]* now")
PLANAR_TARGET = re.compile(r"Target x = ([+-][\d.]+), y = ([+-][\d.]+)")
ROBOT_TARGET = re.compile(r"Target x = ([+-][\d.]+), y = ([+-][\d.]+), z = ([+-][\d.]+) mm")
LENGTHS = re.compile(r"bones ([\d., ]+) long")

LEGEND_JS = """() => {
  const block = [...document.querySelectorAll('div')].find(d => (d.getAttribute('style') || '').includes('1.45'));
  if (!block) return [];
  return [...block.children].map(line => {
    const swatch = line.querySelector('span');
    const style = swatch ? getComputedStyle(swatch) : null;
    return {text: line.innerText.replace('✕', '').trim(), background: style ? style.backgroundImage + ' '
            + style.backgroundColor : '', color: style ? style.color : '', cross: line.innerText.includes('✕'),
            dot: swatch ? style.borderRadius === '50%' : false};
  });
}"""


@dataclass(frozen=True)
class Readout:
    """The panel's numbers as printed: the step shown, the highlighted sample's error now and at t = 0."""

    state: int
    last: int
    t: int
    sample: int
    samples: int
    error_now: float  # bone lengths (planar) or mm (a robot's hand position)
    error_final: float | None


@dataclass(frozen=True)
class LegendEntry:
    text: str
    colors: tuple[tuple[int, int, int], ...]  # the swatch's colour, or both ends of its ramp
    shape: str  # line, dot or cross


def panel_text(page) -> str:
    return page.evaluate("() => document.body.innerText")


def readout(text: str) -> Readout | None:
    """The Readouts folder's step and error line; None while it shows none (before the first solve)."""
    step = STEP.search(text)
    error = TIP_ERROR.search(text) or HAND_ERROR.search(text)
    if step is None or error is None:
        return None
    final = TIP_ERROR.search(text)
    return Readout(
        state=int(step[1]), last=int(step[2]), t=int(step[3]), sample=int(error[1]), samples=int(error[2]),
        error_now=float(error[3]), error_final=float(final[4]) if final else None,
    )  # fmt: skip


def planar_target(text: str) -> np.ndarray | None:
    found = PLANAR_TARGET.search(text)
    return None if found is None else np.array([float(found[1]), float(found[2])])


def robot_target(text: str) -> np.ndarray | None:
    """The target's position in metres, as the panel prints it in mm."""
    found = ROBOT_TARGET.search(text)
    return None if found is None else np.array([float(found[i]) for i in (1, 2, 3)]) / 1000


def link_lengths(text: str) -> np.ndarray:
    """The planar arm's link lengths, from the Model folder's text."""
    return np.array([float(value) for value in LENGTHS.search(text)[1].split(",")])


def slider_t(page) -> int:
    """The timestep slider's value, t (T: pure noise), as the page holds it."""
    return int(float(page.locator("[role=slider]").first.get_attribute("aria-valuenow")))


def rgb_values(css_text: str) -> list[tuple[int, int, int]]:
    return [tuple(int(v) for v in match) for match in re.findall(r"rgba?\((\d+), (\d+), (\d+)", css_text)]


def legend(page) -> list[LegendEntry]:
    """The Legend folder's lines: each swatch's colours (a ramp: both ends) and its text."""
    entries = []
    for line in page.evaluate(LEGEND_JS):
        if line["cross"]:
            colors, shape = rgb_values(line["color"])[:1], "cross"
        else:
            found = [c for c in rgb_values(line["background"]) if c != (0, 0, 0)]
            colors, shape = found[:2], "dot" if line["dot"] else "line"
        entries.append(LegendEntry(line["text"], tuple(colors), shape))
    return entries


def project(camera, box, points) -> np.ndarray:
    """World points (..., 3) -> page pixels (..., 2) through a pinhole at the page's camera (vertical fov)."""
    points = np.asarray(points, dtype=np.float64)
    position, look_at = np.asarray(camera.position, float), np.asarray(camera.look_at, float)
    forward = (look_at - position) / np.linalg.norm(look_at - position)
    up = np.asarray(camera.up_direction, float)
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-9:  # looking straight along "up" (the planar view looks down z)
        right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    x0, y0, width, height = box
    focal = (height / 2) / math.tan(camera.fov / 2)
    relative = points - position
    depth = relative @ forward
    u = x0 + width / 2 + focal * (relative @ right) / depth
    v = y0 + height / 2 - focal * (relative @ true_up) / depth
    return np.stack((u, v), axis=-1)


def near_color(image: np.ndarray, color, tolerance: float) -> np.ndarray:
    """Mask of pixels within `tolerance` (largest channel difference) of `color`."""
    return np.abs(image[..., :3].astype(int) - np.asarray(color, int)).max(axis=-1) <= tolerance


def red_mask(image: np.ndarray) -> np.ndarray:
    pixels = image.astype(int)
    return (pixels[..., 0] > 170) & (pixels[..., 1] < 90) & (pixels[..., 2] < 90)


def orange_mask(image: np.ndarray) -> np.ndarray:
    """The tip markers' oranges, faint to dark: red high, green well above blue (a red blended with white keeps
    green equal to blue, so the target's cross never counts)."""
    r, g, b = (image[..., channel].astype(int) for channel in range(3))
    return (r > 200) & (g - b > 25) & (r - b > 45)


def blobs(mask: np.ndarray, min_pixels: int = 6) -> list[tuple[np.ndarray, int]]:
    """(centre (u, v), pixel count) of each connected patch of `mask` with at least `min_pixels` pixels."""
    labels, count = ndimage.label(mask)
    found = []
    for index in range(1, count + 1):
        rows, cols = np.nonzero(labels == index)
        if len(rows) >= min_pixels:
            found.append((np.array([cols.mean(), rows.mean()]), len(rows)))
    return found


def chroma(image: np.ndarray) -> np.ndarray:
    pixels = image[..., :3].astype(int)
    return pixels.max(axis=-1) - pixels.min(axis=-1)


def hue(colors: np.ndarray) -> np.ndarray:
    """Hue in degrees of RGB colours (..., 3)."""
    rgb = np.asarray(colors, dtype=np.float64) / 255
    high, low = rgb.max(axis=-1), rgb.min(axis=-1)
    spread = np.maximum(high - low, 1e-9)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    value = np.where(high == r, ((g - b) / spread) % 6, np.where(high == g, (b - r) / spread + 2, (r - g) / spread + 4))
    return 60 * value
