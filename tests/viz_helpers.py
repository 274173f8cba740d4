"""Shared helpers of the viewer's tests: an in-process app on a free port, gizmo moves, the real browser."""

from __future__ import annotations

import asyncio
import contextlib
import io
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

import ikdp
from ikdp import SolveResult
from ikdp_viz.screenshot import CHROMIUM_ARGS, NO_FADE_CSS  # noqa: F401  (the browser tests take them from here)

CHROMIUM = "/usr/bin/chromium"
BROWSER_TIMEOUT = 60.0  # seconds, for anything the browser has to render
SETTLE_IN_PAGE = 1.5  # seconds the page gets to draw a solve (software WebGL is slow)


def shipped_solver_or_skip(name: str) -> ikdp.Solver:
    """The shipped model `name`, loaded; the test is skipped where this checkout does not ship it."""
    from ikdp.shipped import list_shipped, shipped_checkpoint

    if name not in {path.stem for path in list_shipped()}:
        pytest.skip(f"the shipped {name} is not there")
    return ikdp.load(shipped_checkpoint(name))


@contextlib.contextmanager
def running_app(solver: ikdp.Solver, **options):
    """A VizApp on a fresh viser server bound to a free local port; closed on exit."""
    import viser  # here, so the scene tests that share these helpers never import viser

    from ikdp_viz.app import VizApp

    with contextlib.redirect_stdout(io.StringIO()):  # viser's banner
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = VizApp(server, solver, **options)
    try:
        yield app
    finally:
        app.close()
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def drag_gizmo(app, x: float, y: float, phase: str = "update") -> None:
    """Do what viser does when a browser drags the target's gizmo: set its pose, then fire its callback."""
    import viser

    gizmo = app.gizmo
    gizmo._impl.position = np.array([x, y, 0.0])  # as viser's handler does with the page's message
    event = viser.TransformControlsEvent(client=None, client_id=None, target=gizmo, phase=phase)
    loop = app.server.get_event_loop()
    asyncio.run_coroutine_threadsafe(app.on_gizmo_update(event), loop).result(timeout=10)


def solves_shown_by_a_robot_drag(app, step: float = 0.05) -> list:
    """Drag a robot's gizmo `step` metres along x (one "update"), let it settle; every solve drawn, in order."""
    shown = []
    original = app.writer._show_solve
    app.writer._show_solve = lambda solved, newest: (shown.append(solved), original(solved, newest))[1]
    moved = np.concatenate([app.target[:3] + np.array([step, 0.0, 0.0]), app.target[3:]])
    app.move_target(moved, from_gizmo=True, dragging=True)
    settle(app)
    return shown


def settle(app) -> None:
    assert app.wait_until_still(timeout=60), "the app did not finish solving and animating"


def missing_browser(message: str) -> None:
    """In CI (CI=true) a missing browser fails the test; elsewhere it skips it."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(message + " (CI=true: the browser tests must run)")
    pytest.skip(message)


def chromium_or_skip() -> str:
    """Debian's chromium, and Playwright to drive it."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        missing_browser("playwright is not installed")
    path = CHROMIUM if os.path.exists(CHROMIUM) else shutil.which("chromium")
    if path is None:
        missing_browser(f"chromium not found at {CHROMIUM} or on PATH")
    return path


def canvas_box(page) -> tuple[float, float, float, float]:
    """(x, y, width, height) of viser's WebGL canvas in page pixels: the largest canvas on the page."""
    boxes = page.evaluate(
        "() => [...document.querySelectorAll('canvas')].map(c => { const r = c.getBoundingClientRect();"
        " return [r.x, r.y, r.width, r.height]; })"
    )
    return tuple(max(boxes, key=lambda box: box[2] * box[3]))


def project(app, box, points: np.ndarray) -> np.ndarray:
    """World points (..., 2 or 3) -> page pixels (..., 2) through the app's initial camera (top-down pinhole)."""
    points = np.asarray(points, dtype=np.float64)
    heights = points[..., 2] if points.shape[-1] == 3 else np.zeros(points.shape[:-1])
    camera = app.server.initial_camera
    look_at = np.asarray(camera.look_at)
    distance = float(camera.position[2]) - heights
    x0, y0, width, height = box
    focal = (height / 2) / math.tan(camera.fov / 2)
    u = x0 + width / 2 + focal * (points[..., 0] - look_at[0]) / distance
    v = y0 + height / 2 - focal * (points[..., 1] - look_at[1]) / distance
    return np.stack((u, v), axis=-1)


def dark_fraction(image: np.ndarray, pixels: np.ndarray, *, radius: int = 2, threshold: int = 90) -> float:
    """Share of `pixels` (M, 2) with a dark pixel (every channel < threshold) within `radius` of them."""
    height, width, _ = image.shape
    found = 0
    for u, v in np.rint(pixels).astype(int):
        rows = slice(max(0, v - radius), min(height, v + radius + 1))
        window = image[rows, max(0, u - radius) : min(width, u + radius + 1)]
        found += bool(window.size and (window[..., :3].max(axis=-1) < threshold).any())
    return found / max(1, len(pixels))


def canvas_changed_share(page, before: np.ndarray, after: np.ndarray, *, threshold: int = 40) -> float:
    """The share of the canvas's pixels whose largest channel moved by more than `threshold` between two shots."""
    x, y, width, height = (int(value) for value in canvas_box(page))
    changed = np.abs(after[y : y + height, x : x + width].astype(int) - before[y : y + height, x : x + width])
    return float((changed.max(axis=-1) > threshold).mean())


def read_png(data: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


def write_png(data: bytes, path: Path) -> None:
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_bytes(data)


def hand_made_result() -> SolveResult:
    """N=2 unit links, K=2 samples, S=2 steps, headings chosen so every joint is known in closed form."""
    half_pi = math.pi / 2
    trajectory = torch.tensor(
        [
            [[[half_pi, half_pi], [math.pi, 0.0]]],  # t = T: straight up; folded back onto the base
            [[[0.0, half_pi], [0.0, -half_pi]]],  # an elbow
            [[[0.0, 0.0], [half_pi, 0.0]]],  # final: straight along +x; an L
        ],
        dtype=torch.float64,
    )  # (S+1, B=1, K=2, N=2)
    final = trajectory[-1]
    target = torch.tensor([[2.0, 0.0]], dtype=torch.float64)
    error = (ikdp.tip_position(final) - target[:, None]).norm(dim=-1)
    return SolveResult(
        angles=final,
        tip_error=error,
        trajectory=trajectory,
        timesteps=[1, 0],
        reachable=torch.tensor([True]),
        raw_angles=final,
        raw_tip_error=error,
    )


def open_page_collecting_errors(browser, app, *, height: int = 900) -> tuple[object, list[str]]:
    """A connected page on `app`, and the list every page error and console error is appended to."""
    errors: list[str] = []
    page = browser.new_page(viewport={"width": 1280, "height": height})
    page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
    page.on("pageerror", lambda error: errors.append(f"pageerror: {error}"))
    page.goto(f"http://127.0.0.1:{app.server.get_port()}")
    page.get_by_text("Connected", exact=True).wait_for(timeout=BROWSER_TIMEOUT * 1000)
    return page, errors


# A WebGL canvas painted red by a compiled shader (as viser's scene is drawn, not just cleared): a browser that
# shows no red here cannot draw the viewer at all
RED_CANVAS = """<canvas id='c' width='64' height='64'></canvas><script>
const gl = document.getElementById('c').getContext('webgl');
if (gl) {
  const shader = (kind, text) => { const s = gl.createShader(kind); gl.shaderSource(s, text); gl.compileShader(s);
                                   return s; };
  const program = gl.createProgram();
  gl.attachShader(program, shader(gl.VERTEX_SHADER, 'attribute vec2 p; void main() { gl_Position = vec4(p, 0, 1); }'));
  gl.attachShader(program, shader(gl.FRAGMENT_SHADER, 'void main() { gl_FragColor = vec4(1, 0, 0, 1); }'));
  gl.linkProgram(program); gl.useProgram(program);
  gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  const p = gl.getAttribLocation(program, 'p'); gl.enableVertexAttribArray(p);
  gl.vertexAttribPointer(p, 2, gl.FLOAT, false, 0, 0);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
}</script>"""


class RenderingBrowser:
    """A chromium launched through Playwright and seen to draw WebGL; relaunched when it does not.

    In three CI runs the first browser module's page stayed white (panel and canvas, the whole page) for a
    minute, through a reload; every later module, each with a browser of its own, drew at once, and the module
    alone never failed. So the remedy is a new browser, tried before any test uses it.
    """

    def __init__(self, playwright, executable: str, args: list[str], attempts: int = 3):
        self.playwright, self.executable, self.args = playwright, executable, args
        self.browser = None
        self.relaunch(attempts)

    def relaunch(self, attempts: int = 3) -> None:
        for attempt in range(1, attempts + 1):
            self.close()
            self.browser = self.playwright.chromium.launch(executable_path=self.executable, args=self.args)
            console = self.draws_red()
            if console is None:
                return
            print(f"chromium drew no WebGL (launch {attempt} of {attempts}); its console: {console}")
        pytest.fail(f"chromium drew no WebGL canvas in {attempts} launches")

    def draws_red(self, timeout: float = 20.0) -> list[str] | None:
        """None once a WebGL canvas shows red; else what the page's console said."""
        import time

        console: list[str] = []
        page = self.browser.new_page(viewport={"width": 200, "height": 200})
        try:
            page.on("console", lambda message: console.append(message.text))
            page.set_content(RED_CANVAS)
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                image = read_png(page.screenshot())
                if ((image[..., 0] > 200) & (image[..., 1] < 50) & (image[..., 2] < 50)).sum() > 1000:
                    return None
                time.sleep(0.2)
            return console
        finally:
            page.close()

    def new_page(self, **options):
        return self.browser.new_page(**options)

    def close(self) -> None:
        if self.browser is not None:
            self.browser.close()
            self.browser = None
