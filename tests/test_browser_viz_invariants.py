"""Every claim on the viewer's page, checked against what the page draws, through seeded random interactions.

A sequence of 10 actions (type a target, drag the gizmo, scrub the timestep slider, play and pause, toggle views,
compare with another sampler, change K, the sampler and the seed, lock a joint and free it, switch models) is drawn
from a seeded generator and done in Debian's chromium, on the planar default arm and on the Panda. After each action,
once the page is still, invariants are read from the page alone, its texts and its pixels (tests/page_reading.py),
placed through the camera the page reports:
- the step label and the timestep slider agree, and the drawn state with them: the highlighted tip's marker is as
  far from the target as the readout's error at that step says (within a few pixels);
- the target's red cross is drawn where the Target text says; a robot's highlighted robot comes as close to the
  target as its readout's hand error says;
- every legend entry's colour is drawn, and every coloured patch drawn has a legend entry of its hue;
- "Constraints hold for n of n" with a joint locked: every drawn arm's first link is at the locked angle;
- a typed target outside the reach is said to be clamped, onto the reach circle.

Each sequence is reproduced from its seed, printed in the failure message with the screenshot of the failing page;
`IKDP_INVARIANT_SEED=7 pytest tests/test_browser_viz_invariants.py` runs that seed alone.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from page_reading import (
    blobs,
    chroma,
    hue,
    legend,
    link_lengths,
    near_color,
    orange_mask,
    panel_text,
    planar_target,
    project,
    readout,
    red_mask,
    robot_target,
    slider_t,
)
from scipy import ndimage
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

PLANAR_MODEL = "ikdp_n4"
ROBOT_MODEL = "ikdp_panda"
ACTIONS = 10  # per sequence: a few minutes for all seeds and both arms on two cores with software WebGL
SEEDS = (1, 2)
TIP_PIXELS = 4.0  # beyond one marker radius, how far the orange patch may sit from the scene's tip
LOCK_DEGREES = 3.0  # the drawn first link's angle against the locked value


def seeds() -> tuple[int, ...]:
    """The seeds to run: IKDP_INVARIANT_SEED alone when set (to rerun a failure), else SEEDS."""
    chosen = os.environ.get("IKDP_INVARIANT_SEED")
    return (int(chosen),) if chosen else SEEDS


@dataclass
class Page:
    """One app and one page on it; `app` is used only to wait until it is still, never to read what it drew."""

    app: object
    page: object
    errors: list[str]
    shots: Path
    first_target: np.ndarray | None = None
    typed_far: bool = False  # the last action typed a target outside the reach
    log: list[str] = field(default_factory=list)

    def still(self) -> None:
        settle(self.app)
        deadline = time.monotonic() + BROWSER_TIMEOUT
        previous = None
        while time.monotonic() < deadline:  # until two shots a little apart are the same picture and texts
            time.sleep(0.4)
            now = (self.page.screenshot(), panel_text(self.page))
            if previous is not None and now == previous:
                return
            previous = now

    def camera(self):
        clients = list(self.app.server.get_clients().values())
        return clients[0].camera  # the page's camera, as the page reports it

    def control(self, label: str, kind: str = "input"):
        """The page's `kind` elements in the panel row labelled `label` (viser lays out a label and its inputs). A
        label's element may hold <wbr> breaks: viser breaks a robot joint's name at its underscores."""
        marker = f"inv-{abs(hash((label, kind))) % 10**8}"
        found = self.page.evaluate(
            """([label, kind, marker]) => {
              const labels = [...document.querySelectorAll('label, p, span, div')]
                .filter(e => [...e.children].every(c => c.tagName === 'WBR') && e.textContent.trim() === label);
              for (const node of labels) {
                let row = node.parentElement;
                for (let up = 0; up < 4 && row; up++, row = row.parentElement) {
                  const inputs = [...row.querySelectorAll(kind)].filter(i => i.type !== 'hidden');
                  if (inputs.length) { inputs.forEach(i => i.setAttribute('data-inv', marker)); return inputs.length; }
                }
              }
              return 0; }""",
            [label, kind, marker],
        )
        assert found, f"no control labelled {label!r} on the page"
        return self.page.locator(f"[data-inv={marker}]")

    def type_number(self, label: str, value, index: int = 0) -> None:
        field_ = self.control(label).nth(index)
        field_.fill(str(value))
        field_.press("Enter")

    def choose(self, label: str, option: str | None, rng=None, avoid: str | None = None) -> str:
        """Pick `option` (or a random other one, not `avoid`) from the dropdown labelled `label`; the option picked."""
        self.page.get_by_label(label, exact=True).click()
        options = self.page.get_by_role("option").all_inner_texts()
        if option is None:
            current = self.page.get_by_label(label, exact=True).input_value()
            others = [o for o in options if o not in (current, avoid)] or options
            option = others[int(rng.integers(len(others)))]
        self.page.get_by_role("option", name=option, exact=True).click()
        return option

    def click(self, text: str) -> None:
        self.page.get_by_text(text, exact=True).first.click()


# ------------------------------------------------------------------ the actions, each drawn from the generator


def type_target(ui: Page, rng, robot: bool) -> str:
    text = panel_text(ui.page)
    if robot:  # about the first target, well inside the reach (a target out of it has a test of its own below)
        point = np.rint(1000 * ui.first_target + rng.uniform(-150, 150, 3)).astype(int)
        for index, value in enumerate(point):
            ui.type_number("x, y, z (mm)", value, index)
        ui.click("Solve this target")
        return f"typed the target ({point[0]}, {point[1]}, {point[2]}) mm"
    reach = float(np.sum(link_lengths(text)))
    far = rng.random() < 0.25
    radius = reach * (rng.uniform(1.3, 2.0) if far else rng.uniform(0.3, 0.95))
    angle = rng.uniform(-np.pi, np.pi)
    point = np.round(radius * np.array([np.cos(angle), np.sin(angle)]), 2)
    for index, value in enumerate(point):
        ui.type_number("x, y", value, index)
    ui.click("Solve this target")
    ui.typed_far = far
    return f"typed the target ({point[0]}, {point[1]}){' outside the reach' if far else ''}"


def drag_planar_gizmo(ui: Page, rng) -> str:
    """A mouse drag on the gizmo's x or y arrow, kept within a bone length or so of the first target: farther, a
    drag stops short of the reach (a known defect with a test of its own below)."""
    page, camera = ui.page, ui.camera()
    box = canvas_box(page)
    target = planar_target(panel_text(page))
    axis = int(rng.integers(2))
    scale = float(ui.app.gizmo.scale)  # the gizmo's size in world units: where its arrows are
    direction = np.eye(2)[axis]
    grip_world = np.append(target + 0.6 * scale * direction, 0.0)
    distance = float(rng.uniform(-1.2, 1.2))
    end_world = np.clip(target + distance * direction, ui.first_target - 3.5, ui.first_target + 3.5)
    grip, end = project(camera, box, [grip_world, np.append(end_world + 0.6 * scale * direction, 0.0)])
    page.mouse.move(*grip)
    page.mouse.down()
    for step in np.linspace(0, 1, 12)[1:]:
        page.mouse.move(*(grip + step * (end - grip)))
        time.sleep(0.03)
    page.mouse.up()
    page.mouse.move(box[0] + 5, box[1] + 5)  # off the arrow: a hovered arrow turns yellow
    return f"dragged the gizmo's {'xy'[axis]} arrow {end_world[axis] - target[axis]:+.2f} to {np.round(end_world, 2)}"


def drag_robot_gizmo(ui: Page, rng) -> str:
    """The robot's gizmo moved as viser's drag event moves it (its 3-D arrows are not found reliably in pixels)."""
    target = np.asarray(ui.app.target, float)
    offset = rng.uniform(-0.08, 0.08, 3)
    moved = np.concatenate([target[:3] + offset, target[3:]])
    for fraction in (0.5, 1.0):
        partial = np.concatenate([target[:3] + fraction * offset, target[3:]])
        ui.app.move_target(partial if fraction < 1 else moved, from_gizmo=True, dragging=fraction < 1)
        time.sleep(0.1)
    return f"dragged the gizmo by {np.round(1000 * offset).astype(int)} mm"


def scrub(ui: Page, rng) -> str:
    keys = ["Home", "End", "PageUp", "PageDown", "ArrowLeft", "ArrowRight"]
    slider = ui.page.locator("[role=slider]").first
    pressed = [keys[int(rng.integers(len(keys)))] for _ in range(int(rng.integers(1, 6)))]
    for key in pressed:  # focused each time: a key that reaches the canvas turns the camera instead
        slider.press(key)
        time.sleep(0.05)
    return f"scrubbed the timestep slider: {' '.join(pressed)}"


def play_pause(ui: Page, rng) -> str:
    wait = float(rng.uniform(0.2, 1.5))
    ui.page.get_by_role("button", name="Play", exact=True).click()
    time.sleep(wait)
    pause = ui.page.get_by_role("button", name="Pause", exact=True)
    if pause.count():
        pause.click()
        return f"played for {wait:.2f} s and paused"
    return f"played (over before the pause at {wait:.2f} s)"


def toggle_view(ui: Page, rng, robot: bool) -> str:
    choices = ["show trail", "show x̂0", "trail of", "refine (DLS)", "compare with"]
    choice = (choices + ([] if robot else ["joint space view"]))[int(rng.integers(len(choices) + (not robot)))]
    if choice == "trail of":
        return f"trail of: {ui.choose('trail of', None, rng)}"
    if choice == "compare with":  # not the sampler shown: compared with itself the student draws nothing (known)
        shown = ui.page.get_by_label("sampler", exact=True).input_value()
        return f"compare with: {ui.choose('compare with', None, rng, avoid=shown)}"
    ui.control(choice).first.click()
    return f"toggled {choice!r}"


def change_k(ui: Page, rng) -> str:
    k = int(rng.choice([1, 3, 8, 16, 24]))
    ui.type_number("samples K", k)
    return f"K = {k}"


def change_sampler(ui: Page, rng) -> str:
    return f"sampler: {ui.choose('sampler', None, rng)}"


def change_seed(ui: Page, rng) -> str:
    seed = int(rng.integers(0, 1000))
    ui.type_number("seed", seed)
    return f"seed = {seed}"


def toggle_lock(ui: Page, rng, robot: bool) -> str:
    """Lock the first joint (the planar arm's at a random angle) or free it, in the Constraints folder."""
    find = """() => { const label = [...document.querySelectorAll('label, p, span, div')]
        .find(e => [...e.children].every(c => c.tagName === 'WBR') && e.textContent.trim().startsWith('lock '));
        return label && label.checkVisibility() ? label.textContent.trim() : null; }"""
    if ui.page.evaluate(find) is None:
        ui.click("Constraints")  # the folder opens, drawn over a few frames
    deadline = time.monotonic() + 10
    while (label := ui.page.evaluate(find)) is None and time.monotonic() < deadline:
        time.sleep(0.1)
    assert label is not None, "no 'lock ...' control shown in the opened Constraints folder"
    box = ui.control(label).first
    box.scroll_into_view_if_needed()
    if box.is_checked():
        box.click()
        return f"freed {label[5:]}"
    box.click()
    if robot:
        return f"locked {label[5:]} where it is"
    degrees = int(rng.integers(-150, 150))
    ui.page.wait_for_function("el => !el.disabled", arg=ui.control("θ1 (°)").first.element_handle())
    ui.type_number("θ1 (°)", degrees)  # the angle's field is enabled once the joint is locked
    return f"locked θ1 at {degrees}°"


def switch_model(ui: Page, rng) -> str:
    return f"model: {ui.choose('checkpoint', None, rng)}"


def draw_action(ui: Page, rng, robot: bool) -> str:
    actions = [
        lambda: type_target(ui, rng, robot), lambda: drag_robot_gizmo(ui, rng) if robot else drag_planar_gizmo(ui, rng),
        lambda: scrub(ui, rng), lambda: scrub(ui, rng), lambda: play_pause(ui, rng),
        lambda: toggle_view(ui, rng, robot), lambda: change_k(ui, rng), lambda: change_sampler(ui, rng),
        lambda: change_seed(ui, rng), lambda: toggle_lock(ui, rng, robot), lambda: switch_model(ui, rng),
    ]  # fmt: skip
    ui.typed_far = False
    return actions[int(rng.integers(len(actions)))]()


# ------------------------------------------------------------------ the invariants, read from the page


def canvas_pixels(image: np.ndarray, box) -> tuple[np.ndarray, tuple[int, int]]:
    """The canvas's part of a screenshot and its offset."""
    x, y, width, height = (int(value) for value in box)
    return image[y : y + height, x : x + width], (x, y)


def step_agrees(slider: int, read) -> list[str]:
    """The timestep slider's t is the readout's "(t = ...)" of the step shown."""
    if slider != read.t:
        return [f"the slider says t = {slider}, the readout step {read.state} of {read.last} (t = {read.t})"]
    return []


# The tips of the arms the three.js scene holds, [x, y, z, scale] each: viser's batched spheres keep each instance's
# matrix in a texture (translation at 12..14); an instance scaled to 0 is not drawn.
TIPS_JS = """() => { const ref = window.__viserMutable.nodeRefFromName['/arm/tips']; let mesh = null;
  (ref.current ?? ref).traverse((o) => { if (o.isInstancedMesh && mesh === null) mesh = o; });
  const data = mesh.matricesTexture.image.data, out = [];
  for (let i = 0; i < mesh.count; i++) {
    const m = data.slice(16 * i, 16 * i + 16);
    out.push([m[12], m[13], m[14], Math.hypot(m[0], m[1], m[2])]);
  }
  return out; }"""


def scene_tips(page) -> np.ndarray:
    """(M, 3) the tips the page's scene draws (instances scaled to 0 left out)."""
    rows = np.asarray(page.evaluate(f"({TIPS_JS})()"), dtype=np.float64).reshape(-1, 4)
    return rows[rows[:, 3] > 1e-6, :3]


def cross_and_tip(image, box, camera, text: str, read, lengths, tips: np.ndarray, tip_radius: float) -> list[str]:
    """The red cross on the Target text's point; the scene's highlighted tip at the readout's distance; its orange
    marker drawn where the scene puts it.

    The scene's tips are read from the page's three.js scene (`scene_tips`): one of them (all K are drawn with
    every sample's trail shown) is the readout's distance from the target, to the readout's four decimals. The
    marker, a lit sphere, fades from near white (t = T) to orange (t = 0) as the legend's ramp says, by the square of
    the step's share: from half way along the ramp it is seen on white, and an orange patch must be on that tip. Its
    shaded side is too dark for the orange mask, so the patch's centre may sit up to one marker radius off.
    """
    target = planar_target(text)
    centre, one = project(camera, box, [np.append(target, 0.0), np.append(target + [1.0, 0.0], 0.0)])
    per_unit = float(np.linalg.norm(one - centre))
    problems = []
    u, v = np.rint(centre).astype(int)
    if not red_mask(image)[v - 2 : v + 3, u - 2 : u + 3].any():
        problems.append(f"no red cross at the Target text's ({target[0]:+.3f}, {target[1]:+.3f}), pixel ({u}, {v})")
    distances = np.linalg.norm(tips[:, :2] - target, axis=-1)
    gaps = np.abs(distances - read.error_now)
    if not len(tips) or np.min(gaps) > 2e-4:
        problems.append(
            f"the readout puts the highlighted tip {read.error_now:.4f} from the target at step {read.state} of "
            f"{read.last}; the scene's tips are {np.round(distances, 4).tolist()} from it"
        )
        return problems
    tip = tips[int(np.argmin(gaps))]
    if (read.state / max(read.last, 1)) ** 2 < 0.5:
        return problems  # still too faint to be told from the white
    x, y, width, height = (int(value) for value in box)
    patches = blobs(orange_mask(image[y : y + height, x : x + width]))  # the canvas only: the panel has oranges too
    drawn_at = project(camera, box, [tip])[0]
    offsets = [float(np.linalg.norm(patch + [x, y] - drawn_at)) for patch, _ in patches]
    cover = 0.35 * float(np.mean(lengths)) * per_unit  # the cross and the gizmo's middle, drawn over the tips
    cross_cover = float(np.linalg.norm(drawn_at - centre)) <= cover
    if not cross_cover and not any(offset <= tip_radius * per_unit + TIP_PIXELS for offset in offsets):
        problems.append(
            f"no orange marker on the highlighted tip at step {read.state} of {read.last}, pixel "
            f"({drawn_at[0]:.0f}, {drawn_at[1]:.0f}); the orange patches are {[round(o, 1) for o in offsets]} px "
            "from it"
        )
    return problems


def robot_reach(image, box, camera, text: str, read) -> list[str]:
    """The highlighted robot's deep blue comes as close to the target's projection as the readout's hand error.

    The gizmo's own blue (54, 142, 226) has more green than the lit robot (40, 110, 235 and darker), so the mask
    leaves it out; the gizmo, drawn over everything, may hide the hand near the target: 15 px of slack.
    """
    target = robot_target(text)
    centre, aside = project(camera, box, [target, target + [0.0, 0.0, 0.05]])
    per_metre = float(np.linalg.norm(aside - centre)) / 0.05
    x, y, width, height = (int(value) for value in box)
    pixels = image[y : y + height, x : x + width].astype(int)
    robot = (hue(pixels) > 205) & (hue(pixels) < 250) & (chroma(pixels) > 60) & (pixels[..., 1] < 125)
    rows, cols = np.nonzero(robot)
    if not len(rows):
        return ["no highlighted (blue) robot drawn"]
    nearest = float(np.min(np.hypot(cols + x - centre[0], rows + y - centre[1])))
    allowed = (read.error_now / 1000 + 0.03) * per_metre + 15
    if nearest > allowed:
        return [
            f"the readout says the hand is {read.error_now} mm from the target; the highlighted robot's nearest "
            f"pixel is {nearest:.0f} px from it (at most {allowed:.0f} px)"
        ]
    return []


def legend_agrees(canvas: np.ndarray, entries, gizmo_centre, gizmo_radius: float) -> list[str]:
    """Each entry's colour (a ramp: one of its shades) is drawn; each coloured patch drawn matches an entry's hue."""
    problems = []
    canvas_hue, canvas_chroma = hue(canvas), chroma(canvas)
    for entry in entries:
        if not entry.colors:
            continue
        dark = np.array(entry.colors[0 if len(entry.colors) == 1 else -1])
        if np.ptp(dark) > 60:  # a colour: its hue, however the scene's light shades it
            gap = np.abs((canvas_hue - hue(dark) + 180) % 360 - 180)
            found = int(((gap < 20) & (canvas_chroma > 0.5 * np.ptp(dark))).sum())
        else:
            found = 0
        if found < 8:  # a grey, or a ramp's faint end: one of its shades, lit or in the shade of a sphere
            ramp = [entry.colors[0] + (dark - entry.colors[0]) * w for w in np.linspace(0, 1, 6)]
            found += sum(int(near_color(canvas, shade * color, 20).sum()) for color in ramp for shade in (1, 0.9, 0.8))
        if found < 8:
            problems.append(f"the legend's {entry.text!r} {entry.colors} is drawn nowhere ({found} pixels)")
    known = np.array([hue(np.array(c)) for entry in entries for c in entry.colors if np.ptp(c) > 30])
    coloured = canvas_chroma > 35
    if not len(known) or not coloured.any():
        return problems
    gap = np.full(canvas_hue.shape, 360.0)
    for value in known:
        gap = np.minimum(gap, np.abs((canvas_hue - value + 180) % 360 - 180))
    rows, cols = np.indices(gap.shape)
    handle = np.hypot(cols - gizmo_centre[0], rows - gizmo_centre[1]) <= gizmo_radius  # the gizmo: a handle
    stray = coloured & (gap > 25) & ~handle
    # two colours blended along an edge (a green arm over a blue trail) are 1-2 px wide: opened away
    stray = ndimage.binary_opening(stray, np.ones((3, 3), bool))
    if stray.sum() > 20:
        v, u = np.argwhere(stray)[0]
        problems.append(
            f"{int(stray.sum())} coloured pixels match no legend entry (e.g. {tuple(int(c) for c in canvas[v, u])} "
            f"at canvas pixel ({u}, {v}))"
        )
    return problems


def lock_holds(ui: Page, image, box, camera, text: str, lengths) -> list[str]:
    """θ1 locked in the page and "Constraints hold for n of n": every drawn arm's first link is at the locked angle."""
    import re

    held = re.search(r"Constraints hold for (\d+) of (\d+) samples", text)
    if (
        held is None
        or held[1] != held[2]
        or "green; red: not" not in text
        or not ui.page.get_by_text("lock θ1", exact=True).is_visible()
    ):
        return []
    if not ui.control("lock θ1").first.is_checked():
        return []
    degrees = float(ui.control("θ1 (°)").first.input_value())
    (base,) = project(camera, box, [np.zeros(3)])
    per_unit = float(np.linalg.norm(project(camera, box, [[1.0, 0, 0]])[0] - base))
    pixels = image.astype(int)
    arm_hue = hue(pixels)
    # the arms of the step shown: green where they hold, as the readout says (green; red: not); the trail's lines
    # from the base (earlier steps, other angles) are blue or grey
    green = (chroma(pixels) > 60) & (arm_hue > 100) & (arm_hue < 160)
    angles = np.radians(np.arange(-180, 180, 0.5))
    around = np.stack([np.cos(angles), -np.sin(angles)], axis=-1)
    crossed = np.ones(len(angles), bool)
    for share in (0.35, 0.55, 0.75):  # a first link crosses every ring at one angle; another link seldom does
        u, v = np.rint(base + share * lengths[0] * per_unit * around).astype(int).T
        hit = green[v, u]
        crossed &= hit | np.roll(hit, 1) | np.roll(hit, -1) | np.roll(hit, 2) | np.roll(hit, -2)
    on = np.degrees(angles)[crossed]
    if not len(on):
        return [f"θ1 locked at {degrees}° and said to hold for every sample; no green first link is drawn"]
    off = (on - degrees + 180) % 360 - 180  # each drawn pixel's angle from the locked one
    runs = np.split(np.sort(off), np.nonzero(np.diff(np.sort(off)) > 1.0)[0] + 1)  # one run per link crossing
    centres = [float(np.mean(run)) for run in runs]
    if max(abs(centre) for centre in centres) > LOCK_DEGREES:
        drawn = [round(degrees + centre, 1) for centre in centres]
        return [f"θ1 locked at {degrees}° and said to hold for every sample; first links drawn at {drawn}°"]
    return []


def far_target_said(text: str, lengths, box, camera, image) -> list[str]:
    if "Clamped" not in text:
        return ["a target typed outside the reach is not said to be clamped"]
    target = planar_target(text)
    if abs(np.hypot(*target) - np.sum(lengths)) > 0.01:
        return [f"clamped to ({target[0]}, {target[1]}), not on the reach r = {np.sum(lengths)}"]
    return []


def invariants(ui: Page, robot: bool) -> tuple[list[str], np.ndarray]:
    page = ui.page
    shot = page.screenshot()
    text = panel_text(page)
    box = canvas_box(page)
    image = read_png(shot).copy()
    x, y, _, height = (int(value) for value in box)
    image[y + height - 80 : y + height, x : x + 80] = 255  # viser's axes widget, no part of the scene
    camera = ui.camera()
    read = readout(text)
    if read is None:
        return [f"no readout on the page: {text[-400:]!r}"], image
    problems = step_agrees(slider_t(page), read)
    canvas, (x0, y0) = canvas_pixels(image, box)
    if robot:
        problems += robot_reach(image, box, camera, text, read)
        target = robot_target(text)
        centre = project(camera, box, [target])[0] - [x0, y0]
        problems += legend_agrees(canvas, legend(page), centre, 0.25 * box[3])
    else:
        lengths = link_lengths(text)
        tip_radius = ui.app.writer.view.sizes.tip
        problems += cross_and_tip(image, box, camera, text, read, lengths, scene_tips(page), tip_radius)
        target = planar_target(text)
        centre, one = project(camera, box, [np.append(target, 0.0), np.append(target + [1.0, 0.0], 0.0)])
        radius = 1.1 * float(ui.app.gizmo.scale) * float(np.linalg.norm(one - centre))
        problems += legend_agrees(canvas, legend(page), centre - [x0, y0], radius)
        problems += lock_holds(ui, image, box, camera, text, lengths)
        if ui.typed_far:
            problems += far_target_said(text, lengths, box, camera, image)
    return problems, image


# ------------------------------------------------------------------ the sequences


def shipped_model(model: str):
    """The shipped model `model`, loaded, and the folder it ships in (its other models: the dropdown's)."""
    from ikdp.shipped import shipped_checkpoint

    solver = shipped_solver_or_skip(model)
    return solver, shipped_checkpoint(model).parent


def sequences() -> list:
    return [(model, seed) for model in (PLANAR_MODEL, ROBOT_MODEL) for seed in seeds()]


@pytest.mark.parametrize(("model", "seed"), sequences())
def test_every_claim_on_the_page_holds_through_a_seeded_sequence(browser, model, seed, tmp_path):
    solver, folder = shipped_model(model)
    robot = model == ROBOT_MODEL
    rng = np.random.default_rng([seed, 1 + int(robot)])  # each arm a sequence of its own
    with running_app(solver, animation_seconds=1.0, checkpoint_folder=folder) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app, height=900)
        page.add_style_tag(content=NO_FADE_CSS)
        page.set_default_timeout(BROWSER_TIMEOUT * 1000 / 4)
        ui = Page(app, page, errors, tmp_path)
        ui.still()
        ui.first_target = (robot_target if robot else planar_target)(panel_text(page))
        for number in range(ACTIONS + 1):
            action = "the page as it opens" if number == 0 else draw_action(ui, rng, robot)
            ui.log.append(action)
            print(f"seed {seed} ({model}), action {number}: {action}")
            ui.still()
            problems, image = invariants(ui, robot)
            if problems:  # a page still drawing is not a finding: once more, a little later
                print(f"  rechecking: {problems}")
                time.sleep(2.0)
                ui.still()
                problems, image = invariants(ui, robot)
            shot = tmp_path / f"{model}-seed{seed}-action{number}.png"
            page.screenshot(path=str(shot))
            assert not problems, (
                f"seed {seed} ({model}), action {number}: {action}: "
                + "; ".join(problems)
                + f"\nscreenshot {shot}\nthe sequence: {ui.log}\nrerun: IKDP_INVARIANT_SEED={seed}"
            )
        assert not [e for e in errors if "pageerror" in e], errors
        page.close()


# ------------------------------------------------------------------ defects seen by users, each its own case


# Each page frame while the denoising plays: the timestep slider's t, the readout's step line, and the tips of the
# arms the scene holds (viser's batched spheres keep each instance's matrix in a texture, translation at 12..14).
PLAYING_PROBE = """(seconds) => new Promise((done) => {
  const rows = [], start = performance.now();
  const tips = () => (__TIPS__)().map((tip) => tip.slice(0, 2));
  const tick = (now) => {
    const slider = document.querySelector('[role=slider]');
    const step = /Step (\\d+) of (\\d+) \\(t = (\\d+)\\)/.exec(document.body.innerText);
    rows.push([Number(slider.getAttribute('aria-valuenow')), step ? Number(step[3]) : null, tips()]);
    if (now - start < seconds * 1000) requestAnimationFrame(tick); else done(rows);
  };
  requestAnimationFrame(tick);
})""".replace("__TIPS__", TIPS_JS)


def drawn_t(view, tips) -> int:
    """The t of the state whose K tips the scene holds: the state whose tips these are, to float32 precision."""
    tips = np.asarray(tips, dtype=np.float64)
    distance = np.abs(view.joints[:, :, -1, :] - tips[None]).max(axis=(1, 2))  # (S+1,)
    state = int(np.argmin(distance))
    assert distance[state] < 1e-4, f"the scene's tips are no state of the solve (nearest {distance[state]:.2g} away)"
    return int(view.labels[state])


def test_the_slider_and_step_label_show_the_drawn_state_while_playing(browser, tmp_path):
    """Frame by frame while the K = 4 denoising plays, the slider and the readout's step name the state whose arms
    the scene holds; the slider may trail the scene by the one page frame the panel takes to render."""
    solver, folder = shipped_model(PLANAR_MODEL)
    with running_app(solver, animation_seconds=0.0, target=(-0.01, 1.2), checkpoint_folder=folder) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app, height=900)
        app.panel.samples.value = 4
        app.move_target((-0.01, 1.2))
        settle(app)
        page.wait_for_timeout(1000)
        app.panel.duration.value = 3.0
        app.toggle_play()
        rows = page.evaluate(PLAYING_PROBE, 3.5)
        view = app.solved.view
        drawn = [drawn_t(view, tips) for _, _, tips in rows]
        assert len(set(drawn)) > 10, f"the probe saw too few states drawn to judge: {sorted(set(drawn))}"
        behind = []
        for frame, (slider, step, _) in enumerate(rows):
            shown = {drawn[frame], drawn[max(frame - 1, 0)]}  # this frame's state, or the frame before's
            if slider not in shown or step not in shown:
                behind.append(f"frame {frame}: slider t = {slider}, step t = {step}, drawn t = {drawn[frame]}")
        assert not behind, f"{len(behind)} of {len(rows)} frames disagree: " + "; ".join(behind[:8])
        assert not [e for e in errors if "pageerror" in e], errors
        page.close()


def test_a_planar_drag_reaches_any_point_of_the_reach(browser, tmp_path):
    solver, folder = shipped_model(PLANAR_MODEL)
    with running_app(solver, animation_seconds=0.0, target=(2.2, 1.2), checkpoint_folder=folder) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app, height=900)
        page.add_style_tag(content=NO_FADE_CSS)
        ui = Page(app, page, errors, tmp_path)
        ui.still()
        start = planar_target(panel_text(page))
        goal = np.array([-3.2, 1.2])  # inside the reach (r = 4), 5.4 to the left of the first target
        camera, box = ui.camera(), canvas_box(page)
        scale = float(app.gizmo.scale)
        grip, end = project(camera, box, [[start[0] + 0.6 * scale, start[1], 0.0], [goal[0] + 0.6 * scale, goal[1], 0]])
        page.mouse.move(*grip)
        page.mouse.down()
        for step in np.linspace(0, 1, 20)[1:]:
            page.mouse.move(*(grip + step * (end - grip)))
            time.sleep(0.03)
        page.mouse.up()
        ui.still()
        text = panel_text(page)
        page.screenshot(path=str(tmp_path / "planar-drag.png"))
        reached = planar_target(text)
        assert np.allclose(reached, goal, atol=0.05) or "Clamped" in text, (
            f"dragged to {goal}, the Target text says {reached} and nothing about a limit"
        )
        page.close()


def test_a_robot_target_out_of_reach_is_said_to_be(browser, tmp_path):
    import re

    solver, folder = shipped_model(ROBOT_MODEL)
    with running_app(solver, animation_seconds=0.0, checkpoint_folder=folder) as app:
        settle(app)
        page, errors = open_page_collecting_errors(browser, app, height=900)
        page.add_style_tag(content=NO_FADE_CSS)
        ui = Page(app, page, errors, tmp_path)
        ui.still()
        for index, value in enumerate((2000, 0, 500)):  # 2 m out: the Panda reaches about 0.85 m
            ui.type_number("x, y, z (mm)", value, index)
        ui.click("Solve this target")
        ui.still()
        text = panel_text(page)
        page.screenshot(path=str(tmp_path / "robot-far.png"))
        said = re.search(r"out of (its |the )?reach|outside (its |the )?reach|unreachable|beyond (its |the )?reach|"
                         r"cannot reach|can't reach|not reach", text, re.IGNORECASE)  # fmt: skip
        assert said, f"typed (2000, 0, 500) mm: the page says nothing about the reach:\n{text[:1500]}"
        page.close()
