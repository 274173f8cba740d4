"""A screenshot of the viewer in headless chromium, for the docs: `python -m ikdp_viz.screenshot docs/screenshot.png`.

Starts the app in-process on a free local port, solves one target, opens the
page in Debian's chromium (Playwright, software WebGL) and saves the picture
once the final pose is drawn. Needs the test extras (playwright) and chromium.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import time
from pathlib import Path

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]
NO_FADE_CSS = "canvas { opacity: 1 !important; transition: none !important; }"  # viser fades its canvas in


def main(argv: list[str] | None = None) -> None:
    from ikdp_viz import DEFAULT_CHECKPOINT

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path, help="PNG to write")
    parser.add_argument("--ckpt", default=str(DEFAULT_CHECKPOINT), help="checkpoint to show")
    parser.add_argument("--target", type=float, nargs=2, default=(1.9, 1.5), help="target x y")
    parser.add_argument("--samples", type=int, default=16, help="samples K")
    parser.add_argument("--seed", type=int, default=3, help="sampling seed")
    parser.add_argument("--chromium", default="/usr/bin/chromium", help="browser executable")
    parser.add_argument("--size", type=int, nargs=2, default=(1400, 900), help="viewport width height")
    args = parser.parse_args(argv)

    import torch
    import viser
    from playwright.sync_api import sync_playwright

    import ikdp
    from ikdp_viz import DEFAULT_CHECKPOINT_DIR
    from ikdp_viz.app import VizApp, list_checkpoints

    torch.set_num_threads(1)
    solver = ikdp.load(args.ckpt)
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    checkpoints = list_checkpoints(DEFAULT_CHECKPOINT_DIR, Path(args.ckpt))
    app = VizApp(
        server, solver, checkpoints=checkpoints, solve_now=False, animation_seconds=0.0, target=tuple(args.target)
    )
    app.panel.samples.value = args.samples
    app.panel.seed.value = args.seed
    app.move_target(args.target)
    app.wait_until_still(60)
    try:
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=args.chromium, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": args.size[0], "height": args.size[1]})
            page.goto(f"http://127.0.0.1:{server.get_port()}")
            page.add_style_tag(content=NO_FADE_CSS)
            page.get_by_text("Connected", exact=True).wait_for(timeout=60_000)
            with contextlib.suppress(Exception):  # the software-rendering notice covers a corner of the scene
                page.locator(".mantine-Notification-closeButton").first.click(timeout=5_000)
            page.get_by_text("Sampling", exact=True).click()  # fold it, so the readouts and the plot show
            time.sleep(5.0)  # software WebGL: let a few frames render
            args.output.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(args.output))
            browser.close()
    finally:
        app.close()
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
