"""Viewer latency as a user sees it: a real pointer drags the target's gizmo in chromium; time to the arm's new pixels.

    python -m benchmarks.viz_page_latency                          # planar, Panda, Z1; 30 moves each
    python -m benchmarks.viz_page_latency --models ikdp_n4 --moves 5   # a smoke run

Each model's viewer is started as a user starts it (`python -m ikdp_viz --ckpt MODEL`, one torch thread, through
benchmarks/viz_page_latency_server.py, which only lets this script read the viewer's state) and opened in Debian's
chromium (software WebGL) through Playwright. Once the first solve is drawn and the page is still, the mouse is
pressed on the gizmo's arrow (located by projecting the gizmo through the tab's camera) and moved by `--step-px`
along it and back, one move at a time, each made once the page has been still for `--quiet-ms`.

Measured per move, every timestamp taken in the page with performance.now():
  page: the pointermove event's time to the first frame whose pixels differ from the frame before, outside discs
    around the gizmo's old and new place (the gizmo moves in the page at once; the arm only once the server's
    solve is drawn). The canvas keeps its drawing buffer (`preserveDrawingBuffer`) so a frame can be read back
    after it is drawn; each animation frame is compared, in the page, right after it is drawn.
  server: the server's share of the same move, the gizmo update's arrival in the server to the end of the
    `server.atomic()` block that draws its first solve (the viewer's own `latencies` record).
Results (raw samples, the machine, chromium's version, the load average) go to
benchmarks/results/viz_page_latency.json; the docs' table is rendered from it (benchmarks/render_docs_tables.py).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import queue
import shlex
import signal
import subprocess
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results" / "viz_page_latency.json"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
                 "--disable-background-networking"]  # fmt: skip
# The planar default, the Panda and the Z1
MODELS = ("ikdp_n4", "ikdp_panda", "ikdp_z1")
VIEWPORT = {"width": 1280, "height": 900}
PREFIX = "page-latency: "  # benchmarks/viz_page_latency_server.py's answers
GRIP_ALONG_ARROW = 0.6  # of the gizmo's scale: on its arrow's shaft, clear of the centre and the arrow's tip
MASK_SCALE = 1.35  # the gizmo's disc, in its projected arrow lengths: arrows, their heads and a robot's rings

# Before any page script: every WebGL canvas keeps its drawing buffer, so a frame can be read after it is drawn
KEEP_DRAWING_BUFFER = """
const getContext = HTMLCanvasElement.prototype.getContext;
HTMLCanvasElement.prototype.getContext = function (type, attributes) {
  if (type === 'webgl' || type === 'webgl2') attributes = Object.assign({}, attributes, {preserveDrawingBuffer: true});
  const context = getContext.call(this, type, attributes);
  if (context && (type === 'webgl' || type === 'webgl2')) this.__probeContext = context;
  return context;
};
"""

# In the page: after each animation frame is drawn, compare it with the one before (on a stride-2 grid, outside
# the masks); remember when the page last changed and, once armed, the first change after the pointer moved.
PROBE = """
([threshold, minimum]) => {
  const canvas = [...document.querySelectorAll('canvas')].filter(c => c.__probeContext)
    .sort((a, b) => b.width * b.height - a.width * a.height)[0];
  if (!canvas) return 'no WebGL canvas';
  const gl = canvas.__probeContext;
  const probe = window.__probe = {masks: [], armed: false, moveAt: null, moveHandled: null, changedAt: null,
                                  early: false, lastChange: performance.now(), frames: 0, previous: null, spare: null,
                                  cost: 0, paused: false};
  window.addEventListener('pointermove', event => {
    if (!probe.armed || probe.moveAt !== null) return;
    probe.moveAt = event.timeStamp;
    probe.moveHandled = performance.now();
    probe.framesAtMove = probe.frames;
  }, {capture: true});
  const channel = new MessageChannel();
  channel.port1.onmessage = () => {
    const now = performance.now();
    if (probe.paused) { probe.frames += 1; return; }
    check(now);
    probe.cost += performance.now() - now;  // reading back and comparing: what this probe adds to each frame
  };
  const check = now => {
    const width = gl.drawingBufferWidth, height = gl.drawingBufferHeight;
    const previous = probe.previous;
    const pixels = probe.spare && probe.spare.length === width * height * 4 ? probe.spare
                   : new Uint8Array(width * height * 4);  // two buffers in turn: no 4 MB garbage a frame
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    probe.spare = previous;
    probe.previous = pixels;
    probe.frames += 1;
    if (probe.armed && probe.moveAt !== null) probe.frameTimes.push(now);  // when each frame after the move was seen
    if (!previous || previous.length !== pixels.length) return;
    const box = canvas.getBoundingClientRect(), sx = width / box.width, sy = height / box.height;
    const masks = probe.masks.map(m => [m[0] * sx, height - m[1] * sy, (m[2] * sx) ** 2]);
    let changed = 0, where = null;
    for (let y = 0; y < height && changed < minimum; y += 2) {
      for (let x = 0; x < width; x += 2) {
        const i = 4 * (y * width + x);
        if (Math.abs(pixels[i] - previous[i]) <= threshold && Math.abs(pixels[i + 1] - previous[i + 1]) <= threshold
            && Math.abs(pixels[i + 2] - previous[i + 2]) <= threshold) continue;
        if (masks.some(m => (x - m[0]) ** 2 + (y - m[1]) ** 2 <= m[2])) continue;
        where = where || [x / sx + box.x, (height - y) / sy + box.y];
        if (++changed >= minimum) break;
      }
    }
    if (changed < minimum) return;
    probe.lastChange = now;
    if (!probe.armed) return;
    if (probe.moveAt === null) { probe.early = true; return; }
    probe.changedAt = now;
    probe.changedWhere = where;
    probe.framesToChange = probe.frames - probe.framesAtMove;
    probe.armed = false;
  };
  const frame = () => { channel.port2.postMessage(0); requestAnimationFrame(frame); };
  requestAnimationFrame(frame);
  return null;
}
"""


def rotation_matrix(wxyz) -> np.ndarray:
    """The 3x3 rotation of a unit quaternion (w, x, y, z)."""
    w, x, y, z = np.asarray(wxyz, dtype=np.float64) / np.linalg.norm(wxyz)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def project(points, camera: dict, box) -> np.ndarray:
    """World points (..., 3) -> page pixels (..., 2) through a viser camera (position, wxyz, vertical fov).

    viser's camera frame is OpenCV's: x right, y down, z forward; `box` is the canvas's (x, y, width, height).
    """
    rotation = rotation_matrix(camera["wxyz"])
    seen = (np.asarray(points, dtype=np.float64) - np.asarray(camera["position"])) @ rotation  # world -> camera
    x0, y0, width, height = box
    focal = (height / 2) / math.tan(camera["fov"] / 2)
    return np.stack((x0 + width / 2 + focal * seen[..., 0] / seen[..., 2],
                     y0 + height / 2 + focal * seen[..., 1] / seen[..., 2]), axis=-1)  # fmt: skip


def grip(gizmo: dict, camera: dict, box, axes: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Where to press on the gizmo: (pixel on its longest-looking arrow, that arrow's unit direction on screen,
    the radius in pixels of a disc that covers the whole gizmo). `axes`: how many of its arrows can be dragged."""
    centre = np.asarray(gizmo["position"], dtype=np.float64)
    arrows = rotation_matrix(gizmo["wxyz"])[:, :axes].T * gizmo["scale"]  # (axes, 3): each arrow, world
    ends = project(centre + arrows, camera, box)
    middle = project(centre, camera, box)
    lengths = np.linalg.norm(ends - middle, axis=-1)
    longest = int(np.argmax(lengths))
    direction = (ends[longest] - middle) / lengths[longest]
    return middle + GRIP_ALONG_ARROW * (ends[longest] - middle), direction, float(MASK_SCALE * lengths.max())


def summary(values: list[float]) -> dict:
    if not values:
        return {"n": 0}
    array = np.asarray(values, dtype=np.float64)
    return {"median": float(np.median(array)), "p10": float(np.percentile(array, 10)),
            "p90": float(np.percentile(array, 90)), "n": len(values)}  # fmt: skip


class Viewer:
    """`python -m ikdp_viz --ckpt MODEL` in a process of its own (one torch thread), always killed on exit."""

    def __init__(self, model: str, timeout: float):
        env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
        self.command = [sys.executable, "-m", "benchmarks.viz_page_latency_server", "--ckpt", model, "--port", "0"]
        self.process = subprocess.Popen(self.command, cwd=REPO, env=env, text=True, stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        self.lines: queue.Queue[str] = queue.Queue()
        self.errors: list[str] = []
        threading.Thread(target=self._read, args=(self.process.stdout, self.lines.put), daemon=True).start()
        threading.Thread(target=self._read, args=(self.process.stderr, self.errors.append), daemon=True).start()
        self.url = self._wait_for(lambda line: line.startswith("ikdp-viz: open "), timeout).split()[-1]

    @staticmethod
    def _read(stream, put) -> None:
        for line in stream:
            put(line.rstrip("\n"))

    def _wait_for(self, wanted, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                if self.process.poll() is not None:
                    said = " | ".join(self.errors[-3:])
                    raise RuntimeError(f"the viewer exited ({self.process.returncode}): {said}") from None
                continue
            if wanted(line):
                return line
        raise TimeoutError(f"the viewer said nothing wanted in {timeout:.0f} s: {' | '.join(self.errors[-3:])}")

    def state(self, command: str = "state") -> dict:
        """The viewer's state now (`state`), or once it has nothing left to solve or draw (`still`)."""
        self.process.stdin.write(command + "\n")
        self.process.stdin.flush()
        return json.loads(self._wait_for(lambda line: line.startswith(PREFIX), 90.0)[len(PREFIX) :])

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()  # the viewer stops cleanly on SIGTERM
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)


def wait(page, condition: str, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not page.evaluate(condition):
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what}: not within {timeout:.0f} s")
        time.sleep(0.03)


def wait_still(page, quiet_ms: float, timeout: float) -> None:
    wait(page, f"() => performance.now() - window.__probe.lastChange >= {quiet_ms}", timeout, "the page to be still")


def idle_frame_rate(page, *, paused: bool, seconds: float = 2.0) -> tuple[float, float]:
    """Frames a second of the still page, and the probe's ms a frame (reading back and comparing; 0 when paused)."""
    read = "() => [window.__probe.frames, window.__probe.cost]"
    page.evaluate(f"() => {{ window.__probe.paused = {'true' if paused else 'false'}; }}")
    time.sleep(0.5)
    frames, cost = page.evaluate(read)
    time.sleep(seconds)
    frames_after, cost_after = page.evaluate(read)
    page.evaluate("() => { window.__probe.paused = false; window.__probe.previous = null; }")
    return (frames_after - frames) / seconds, (cost_after - cost) / max(1, frames_after - frames)


def wait_for_camera(viewer: Viewer, timeout: float) -> dict:
    """The viewer's state once the tab's camera has reached the server and stays put (the viewer moves the camera
    of a tab that connects: the first camera the tab reports may be the one it opened with)."""
    deadline = time.monotonic() + timeout
    before = None
    while True:
        state = viewer.state()
        if state["camera"] is not None and state["camera"] == (before or {}).get("camera"):
            return state
        if time.monotonic() > deadline:
            raise TimeoutError("the tab's camera never settled in the server")
        before = state
        time.sleep(0.5)


def measure_model(browser, model: str, args) -> dict:
    """One model: the viewer started, the page opened, `args.moves` drags measured; the viewer always stopped."""
    viewer = Viewer(model, args.timeout)
    page = None
    try:
        page = browser.new_page(viewport=VIEWPORT)
        page.add_init_script(KEEP_DRAWING_BUFFER)
        page.goto(viewer.url)
        page.get_by_text("Connected", exact=True).wait_for(timeout=args.timeout * 1000)
        wait(page, "() => [...document.querySelectorAll('canvas')].some(c => c.__probeContext)", args.timeout,
             "the WebGL canvas")  # fmt: skip
        problem = page.evaluate(PROBE, [args.threshold, args.min_pixels])
        if problem:
            raise RuntimeError(problem)
        time.sleep(1.0)  # the first solve starts playing once the tab connects
        wait_still(page, 1000, args.timeout)  # the first solve drawn to its end
        state = wait_for_camera(viewer, args.timeout)
        box = tuple(page.evaluate(
            "() => { const r = window.__probe && [...document.querySelectorAll('canvas')].filter(c => c.__probeContext)"
            "[0].getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; }"
        ))  # fmt: skip
        idle_fps, probe_ms = idle_frame_rate(page, paused=False)  # the page's frame rate while still, probed
        unprobed_fps, _ = idle_frame_rate(page, paused=True)  # and with the probe counting frames only
        if args.screenshots is not None:
            args.screenshots.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(args.screenshots / f"{Path(model).stem}.png"))
        axes = 2 if model_is_planar(state) else 3
        start, direction, radius = grip(state["gizmo"], state["camera"], box, axes)
        step = args.step_px * direction
        page.mouse.move(*start)
        page.mouse.down()
        origin = page.evaluate("() => performance.timeOrigin")  # epoch ms of the page's performance.now() = 0
        samples: dict[str, list] = {
            "page_ms": [],
            "server_ms": [],
            "to_server_ms": [],
            "from_server_ms": [],
            "pointer_handled_ms": [],
            "frames_to_change": [],
            "frame_intervals_ms": [],
            "changed_at_px": [],
            "missed": 0,
            "early": 0,
        }
        try:
            index = -1
            while len(samples["page_ms"]) < args.moves and index < args.warmup + 2 * args.moves:
                index += 1
                before = len(viewer.state("still")["latencies"])
                wait_still(page, args.quiet_ms, args.timeout)
                here = start + (index % 2) * step
                there = start + ((index + 1) % 2) * step
                centre_here = here - GRIP_ALONG_ARROW * radius / MASK_SCALE * direction  # the gizmo's centre, near
                masks = [[*(centre_here - box[:2]), radius], [*(centre_here + (there - here) - box[:2]), radius]]
                page.evaluate(
                    "masks => Object.assign(window.__probe, {masks, armed: true, moveAt: null, moveHandled: null,"
                    " changedAt: null, early: false, frameTimes: []})",
                    masks,
                )  # fmt: skip
                page.mouse.move(*there)
                deadline = time.monotonic() + args.timeout
                probe = {}
                while time.monotonic() < deadline:
                    probe = page.evaluate("() => ({...window.__probe, previous: null, spare: null})")
                    if probe["changedAt"] is not None or probe["early"]:
                        break
                    time.sleep(0.02)
                after = viewer.state("still")
                drawn = after["latencies"][before:]
                if index == 0 and not drawn:
                    raise RuntimeError(f"dragging the gizmo at {np.round(start, 1)} px moved no target in the server")
                if index < args.warmup:
                    continue
                if probe.get("early"):
                    samples["early"] += 1
                    continue
                if probe.get("changedAt") is None:
                    samples["missed"] += 1
                    continue
                samples["page_ms"].append(probe["changedAt"] - probe["moveAt"])
                samples["pointer_handled_ms"].append(probe["moveHandled"] - probe["moveAt"])
                samples["frames_to_change"].append(probe["framesToChange"])
                seen = [probe["moveAt"], *probe["frameTimes"]]
                samples["frame_intervals_ms"].append([round(b - a, 1) for a, b in zip(seen, seen[1:], strict=False)])
                samples["changed_at_px"].append([round(value, 1) for value in probe["changedWhere"]])
                if drawn:
                    arrival = min(entry[0] for entry in drawn)
                    first = min(entry[1] for entry in drawn if entry[0] == arrival)
                    samples["server_ms"].append(1000 * (first - arrival))
                    arrived = 1000 * (arrival + after["perf_counter_to_epoch"]) - origin  # on the page's clock
                    samples["to_server_ms"].append(arrived - probe["moveAt"])
                    samples["from_server_ms"].append(samples["page_ms"][-1] - samples["to_server_ms"][-1]
                                                     - samples["server_ms"][-1])  # fmt: skip
        finally:
            page.mouse.up()
        command = shlex.join(["python", "-m", "ikdp_viz", "--ckpt", model])
        return {
            **samples,
            "idle_frames_per_second": idle_fps,
            "idle_frames_per_second_unprobed": unprobed_fps,
            "probe_ms_per_frame": probe_ms,
            "grip_px": [float(value) for value in start],
            "gizmo_disc_px": radius,
            "viewer_command": command,
        }
    finally:
        if page is not None:
            page.close()
        viewer.close()


def model_is_planar(state: dict) -> bool:
    """A planar arm's gizmo lies on the z = 0 plane with the identity rotation (a robot's is at its hand)."""
    gizmo = state["gizmo"]
    return abs(gizmo["position"][2]) < 1e-9 and np.allclose(gizmo["wxyz"], [1, 0, 0, 0])


def cpu_model() -> str:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor() or "?"


def chromium_version(path: str) -> str:
    try:
        return subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


PARTS = (  # the page's latency, and its three parts (each on its own samples' median)
    ("page: pointer move -> new pixels", "page_ms"),
    ("  pointer move -> server", "to_server_ms"),
    ("  server: arrival -> drawn", "server_ms"),
    ("  server drawn -> new pixels", "from_server_ms"),
)


def print_table(models: dict, load: tuple) -> None:
    print(f"\nviewer latency in the page, chromium software WebGL, one torch thread; load average {load[0]:.2f}")
    print(f"{'model':16}{'':34}{'median':>8}{'p10':>8}{'p90':>8}{'n':>5}  (ms)")
    for model, result in models.items():
        for index, (label, key) in enumerate(PARTS):
            row = summary(result[key])
            numbers = "".join(f"{row[name]:8.0f}" for name in ("median", "p10", "p90")) if row["n"] else " " * 24
            print(f"{'' if index else model:16}{label:34}{numbers}{row['n']:5d}")
        if result["missed"] or result["early"]:
            print(f"{'':16}{result['missed']} moves drew no change outside the gizmo, {result['early']} changed early")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS), help="shipped models or checkpoint paths")
    parser.add_argument("--moves", type=int, default=30, help="measured drag moves per model")
    parser.add_argument("--warmup", type=int, default=2, help="drag moves first, not counted")
    parser.add_argument("--step-px", type=float, default=12.0, help="how far each move goes along the arrow (px)")
    parser.add_argument("--quiet-ms", type=float, default=1000.0, help="how long the page is still before a move")
    parser.add_argument("--threshold", type=int, default=24, help="a channel change (0-255) that counts as changed")
    parser.add_argument("--min-pixels", type=int, default=3, help="changed pixels (stride 2) that make a change")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds for any one wait")
    parser.add_argument("--output", type=Path, default=RESULTS)
    parser.add_argument("--chromium", default=CHROMIUM)
    parser.add_argument("--screenshots", type=Path, default=None, help="a folder for each page as first drawn")
    args = parser.parse_args(argv)
    for name in ("moves", "timeout", "step_px", "quiet_ms", "min_pixels"):
        if getattr(args, name) <= 0:
            parser.error(f"--{name.replace('_', '-')} {getattr(args, name)}: expected a positive number")
    if args.warmup < 0 or not 0 <= args.threshold <= 255:
        parser.error(f"--warmup {args.warmup} --threshold {args.threshold}: expected warmup >= 0, threshold 0 to 255")
    if not os.path.exists(args.chromium):
        raise SystemExit(f"viz_page_latency: error: chromium not found at {args.chromium} (apt install chromium)")
    try:
        from playwright.sync_api import Error as PlaywrightError
        from playwright.sync_api import sync_playwright
    except ImportError:
        raise SystemExit("viz_page_latency: error: playwright is not installed (pip install playwright)") from None
    import torch

    signal.signal(signal.SIGTERM, signal.default_int_handler)  # a kill unwinds too: the viewer and chromium stop
    load_at_start = os.getloadavg()
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    results = {}
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=args.chromium, args=CHROMIUM_ARGS)
        try:
            for model in args.models:
                print(f"{model}: ", end="", flush=True)
                try:
                    results[model] = measure_model(browser, model, args)
                except (RuntimeError, TimeoutError, PlaywrightError) as error:
                    said = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
                    raise SystemExit(f"\nviz_page_latency: error: {model}: {said}") from None
                print(f"page median {np.median(results[model]['page_ms'] or [float('nan')]):.0f} ms", flush=True)
        finally:
            browser.close()
    load_at_end = os.getloadavg()
    print_table(results, load_at_start)
    record = {
        "command": shlex.join(
            ["python", "-m", "benchmarks.viz_page_latency", *(sys.argv[1:] if argv is None else argv)]
        ),
        "date": started,
        "machine": {
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "torch_threads": 1,
            "torch": torch.__version__,
            "chromium": chromium_version(args.chromium),
            "python": platform.python_version(),
            "load_average_at_start": [round(value, 2) for value in load_at_start],
            "load_average_at_end": [round(value, 2) for value in load_at_end],
        },  # fmt: skip
        "setup": {
            "viewport": VIEWPORT,
            "chromium_args": CHROMIUM_ARGS,
            "moves": args.moves,
            "warmup": args.warmup,
            "step_px": args.step_px,
            "quiet_ms": args.quiet_ms,
            "threshold": args.threshold,
            "min_pixels": args.min_pixels,
        },  # fmt: skip
        "summary": {model: {key: summary(result[key]) for _, key in PARTS} for model, result in results.items()},
        "models": results,
    }
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
