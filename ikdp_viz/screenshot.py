"""A screenshot of the viewer in headless chromium: `python -m ikdp_viz.screenshot --output docs/screenshot.png`.

Starts the app in-process on a free local port, solves one target, opens the
page in Debian's chromium (Playwright, software WebGL) and saves the picture
once the final pose is drawn. Needs the test extras (playwright) and chromium.

Each picture of the viewer (not the `--moments` series) carries a stamp (a PNG text chunk) of what its panel
showed: the controls' labels, the chart's title, axes and series, and the legend. tests/test_viz_docs_images.py
builds the same panel from the command the docs give and compares: a README picture of a chart or control that
no longer exists fails there (so a picture never shows a chart the viewer has dropped).
"""

from __future__ import annotations

import contextlib
import io
import json
import time
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path

from ikdp.shipped import DEFAULT_MODEL

# Debian's chromium with software WebGL, no GPU needed; the browser tests and the frame benchmarks use these too
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--enable-unsafe-swiftshader",
    "--use-angle=swiftshader",
    "--disable-background-networking",
]
# The page counts its own requestAnimationFrame callbacks for `seconds`: [frames, elapsed seconds]
# (benchmarks/viz_frames.py, viz_frame_costs.py)
COUNT_FRAMES = """(seconds) => new Promise((done) => {
  let frames = 0; const start = performance.now();
  const tick = (now) => { frames += 1; if (now - start < seconds * 1000) requestAnimationFrame(tick);
                          else done([frames, (now - start) / 1000]); };
  requestAnimationFrame(tick);
})"""
# viser fades its canvas in with a CSS transition that software rendering advances slowly
NO_FADE_CSS = "canvas { opacity: 1 !important; transition: none !important; }"
STAMP_KEY = "ikdp-viewer-panel"  # the PNG text chunk of a picture's panel stamp


def panel_stamp(panel) -> dict:
    """What the panel shows apart from numbers: each control's label (the Panel's handles in order), the chart's
    title, axes and series, the legend's HTML."""
    labels = []

    def walk(value) -> None:
        if isinstance(getattr(value, "label", None), str):  # a viser handle (a dataclass too)
            if getattr(value, "visible", True):  # a hidden control is not in the picture
                labels.append(value.label)
        elif is_dataclass(value):  # the panel's groups: Panel, LearnControls, ...
            for field in fields(value):
                walk(getattr(value, field.name))

    walk(panel)
    plot = panel.plot
    chart = {"title": plot.title, "axes": [axis.get("label") for axis in plot.axes or ()],
             "series": [series.get("label") for series in plot.series or ()]}  # fmt: skip
    return {"controls": labels, "chart": chart, "legend": panel.learn.legend.content}


def stamp_png(path: Path, stamp: dict) -> None:
    """Write `stamp` into the PNG at `path` (its text chunk STAMP_KEY), the picture unchanged."""
    from PIL import Image, PngImagePlugin

    with Image.open(path) as image:
        image.load()
    info = PngImagePlugin.PngInfo()
    info.add_text(STAMP_KEY, json.dumps(stamp, ensure_ascii=False, sort_keys=True))
    image.save(path, pnginfo=info)


def read_stamp(path: Path) -> dict | None:
    """The panel stamp of the PNG at `path`, or None when it has none (taken before stamps, or elsewhere)."""
    from PIL import Image

    with Image.open(path) as image:
        text = image.info.get(STAMP_KEY)
    return None if text is None else json.loads(text)


def open_viewer_page(playwright, server, *, chromium: str, viewport: tuple[int, int], pixel_ratio: float | None = None):
    """Debian's chromium (software WebGL) on the viewer that `server` serves, once connected: (browser, page).

    `pixel_ratio` pins the canvas's resolution (viser's `fixedDpr`); None leaves viser to lower it after slow frames,
    as a user's page does."""
    browser = playwright.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
    page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})
    query = "" if pixel_ratio is None else f"/?fixedDpr={pixel_ratio:g}"
    page.goto(f"http://127.0.0.1:{server.get_port()}{query}")
    page.get_by_text("Connected", exact=True).wait_for(timeout=120_000)
    return browser, page


@dataclass(frozen=True)
class ScreenshotConfig:
    """A screenshot of the viewer in headless chromium, for the docs."""

    output: Path  # PNG to write
    ckpt: str = DEFAULT_MODEL  # a shipped model's name or a checkpoint's path
    target: tuple[float, ...] | None = (1.9, 1.5)  # target x y (a robot: x y z w qx qy qz; None: its first target)
    samples: int = 16  # samples K
    seed: int = 3  # sampling seed
    chromium: str = "/usr/bin/chromium"  # browser executable
    size: tuple[int, int] = (1400, 900)  # viewport width height
    trail_of: str = "highlighted"  # the panel's "trail of": highlighted or "all samples"
    show_estimate: bool = False  # tick "show x̂0"
    joint_space: bool = False  # tick "joint space view"
    prior: bool = False  # press "Draw from the prior" once solved
    timestep: int | None = None  # the step shown (None: t = 0, the final pose)
    refine_steps: int = 0  # tick "refine" with this many steps (0: off)
    sampler: str | None = None  # the panel's sampler, or student (None: the model's default, as the viewer opens)
    compare: str = "off"  # "compare with": off, ddim, dpmpp2m, ddpm, student
    saved_page: Path | None = None  # instead: open this saved HTML page (a shared denoising) from disk, no server
    wait: float = 6.0  # seconds a saved page plays before the picture
    target_kind: str = "full pose"  # Constraints folder, pose models: "position only", "free x axis", ... (open)
    obstacle: tuple[float, float, float, float] | None = None  # Constraints: drop one at x y z radius (open)
    # the first minute: the command line's viewer (the first solve waits at pure noise, plays when the tab opens,
    # over 4 s), one picture at each of these seconds into the animation: <output>_<i>.png
    moments: tuple[float, ...] | None = None


def screenshot_saved_page(page_path: Path, output: Path, *, chromium: str, size: tuple[int, int], wait: float) -> None:
    """A page saved on disk (a shared denoising, record.py) opened as file:// with no server, after `wait` s."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": size[0], "height": size[1]})
        page.goto(Path(page_path).resolve().as_uri())
        page.add_style_tag(content=NO_FADE_CSS)  # a recording shows no notification (record.with_legend)
        time.sleep(wait)
        output.parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(output))
        browser.close()


def configured_app(args: ScreenshotConfig):
    """(server, app): the viewer in-process on a free local port, set as `args` asks and solved (no browser)."""
    import torch
    import viser

    import ikdp
    from ikdp.shipped import shipped_dir
    from ikdp_viz.app import VizApp, list_checkpoints
    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.models import checkpoint_path
    from ikdp_viz.panel import DEFAULT_DURATION
    from ikdp_viz.student import opening_sampler

    torch.set_num_threads(1)
    path = checkpoint_path(args.ckpt)
    solver = ikdp.load(path)
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    checkpoints = list_checkpoints(shipped_dir(), path)
    app = VizApp(
        server,
        solver,
        checkpoints=checkpoints,
        checkpoint_folder=shipped_dir(),  # as the command line opens it: the model's student found there
        solve_now=False,
        animation_seconds=0.0 if args.moments is None else DEFAULT_DURATION,
        target=None if args.target is None else tuple(args.target),
        wait_for_tab=args.moments is not None,
    )
    app.panel.samples.value = args.samples
    app.panel.seed.value = args.seed
    app.panel.learn.trail_of.value = args.trail_of
    app.panel.show_estimate.value = args.show_estimate
    app.panel.joint_space.show.value = args.joint_space
    app.panel.learn.compare.value = args.compare
    opening = opening_sampler(arm_kind(app.solver), app.session.student, app.asked_for_student)
    app.panel.sampler.value = args.sampler or opening[0]
    if args.refine_steps:
        app.panel.refine_steps.value = args.refine_steps
        app.panel.refine.value = True
    constraints = app.constraint_controls
    if args.target_kind != "full pose":
        if constraints.target_kind is None:
            raise ValueError(f"target_kind: {args.target_kind!r} needs a pose model, {args.ckpt} is not one")
        constraints.target_kind.value = args.target_kind
    if args.obstacle is not None:
        constraints.add_obstacle(position=args.obstacle[:3], radius=args.obstacle[3])
    app.move_target(app.target)  # args.target pulled into the workspace, or the arm's first target
    app.wait_until_still(60)  # (waiting at pure noise for the tab, with `moments`)
    if args.timestep is not None:
        app.panel.timestep.value = args.timestep
    if args.prior:
        app.draw_prior()
    return server, app


def check_browser(chromium: str) -> None:
    """Exit with one line, before any work, without Playwright or the browser it drives."""
    import importlib.util
    import os

    if importlib.util.find_spec("playwright") is None:
        raise SystemExit("ikdp_viz.screenshot: error: needs playwright: pip install 'ikdp[test]'")
    if not os.access(chromium, os.X_OK):
        raise SystemExit(f"ikdp_viz.screenshot: error: --chromium {chromium}: no browser there (apt install chromium)")


def main(argv: list[str] | None = None) -> None:
    import tyro

    args = tyro.cli(ScreenshotConfig, args=argv)
    check_browser(args.chromium)
    if args.saved_page is not None:
        screenshot_saved_page(args.saved_page, args.output, chromium=args.chromium, size=args.size, wait=args.wait)
        print(f"wrote {args.output}")
        return

    from playwright.sync_api import sync_playwright

    server, app = configured_app(args)
    constrained = args.target_kind != "full pose" or args.obstacle is not None
    try:
        with sync_playwright() as playwright:
            browser, page = open_viewer_page(playwright, server, chromium=args.chromium, viewport=args.size)
            page.add_style_tag(content=NO_FADE_CSS)
            if args.moments is not None:  # the page as a newcomer sees it: nothing clicked
                # The tab's connection played the denoising; software WebGL's first screenshots take seconds, so
                # after a warm-up picture the same animation is played again (Play at the end starts from t = T)
                app.wait_until_still(60)
                page.screenshot()
                app.toggle_play()
                connected = time.monotonic()
                for index, moment in enumerate(args.moments):
                    time.sleep(max(0.0, connected + moment - time.monotonic()))
                    name = args.output.with_name(f"{args.output.stem}_{index + 1}{args.output.suffix}")
                    name.parent.mkdir(parents=True, exist_ok=True)
                    page.screenshot(path=str(name))
                    print(f"wrote {name} ({time.monotonic() - connected:.1f} s into the animation)")
                browser.close()
                return
            for folder in ("Noise schedule", "Sampling"):  # fold them, so the legend, the readouts and the plot show
                page.get_by_text(folder, exact=True).click()
            if constrained:  # open the Constraints folder (at the panel's foot, under the readouts)
                page.get_by_text("Constraints", exact=True).click()
            time.sleep(5.0)  # software WebGL: let a few frames render
            args.output.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(args.output))
            stamp_png(args.output, panel_stamp(app.panel))
            browser.close()
    finally:
        app.close()
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
