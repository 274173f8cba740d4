"""The viewer as `python -m ikdp_viz` runs it, answering what a page-latency run needs to know on stdin/stdout.

    python -m benchmarks.viz_page_latency_server --ckpt ikdp_n4 --port 0   # started by benchmarks/viz_page_latency.py

The same `ikdp_viz.__main__.main` with the same flags; the only addition is a reader of stdin: each line `state`
is answered on stdout by one line `page-latency: {json}` holding the gizmo's pose and scale, the first connected
tab's camera, and the server's `(arrival, drawn, newest)` latencies (`VizApp.latencies`: a gizmo update's arrival
to the end of the `server.atomic()` block that draws its solve, perf_counter seconds, and the offset that makes
them epoch seconds). A line `still` waits (60 s at most) until the viewer has no solve waiting, running or left to
draw, then answers the same with `"still": true` (false: it did not get there). When stdin closes the viewer
stops, so it never outlives the benchmark. The viewer itself is not changed:
the app is only kept when it is made, so that its public state can be read.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
import time

PREFIX = "page-latency: "


def state(app) -> dict:
    """What the page-latency benchmark reads from the running viewer; `camera` is None until a tab connects."""
    gizmo = app.gizmo
    clients = list(app.server.get_clients().values())
    camera = None
    if clients:
        seen = clients[0].camera
        camera = {"position": seen.position.tolist(), "wxyz": seen.wxyz.tolist(), "fov": float(seen.fov),
                  "aspect": float(seen.aspect)}  # fmt: skip
    return {
        "gizmo": {"position": gizmo.position.tolist(), "wxyz": gizmo.wxyz.tolist(), "scale": float(gizmo.scale)},
        "camera": camera,
        "latencies": [list(entry) for entry in list(app.latencies)],
        "perf_counter_to_epoch": time.time() - time.perf_counter(),  # puts a latency on the page's clock
    }


def answer(apps: list) -> None:
    for line in sys.stdin:
        command = line.strip()
        if command not in ("state", "still"):
            continue
        still = apps[0].wait_until_still(60.0) if command == "still" else None
        reply = {**state(apps[0]), "still": still}
        print(PREFIX + json.dumps(reply), flush=True)
    # stdin closed: the benchmark is gone (even killed outright), so the viewer stops as on Ctrl-C
    os.kill(os.getpid(), signal.SIGTERM)


def main(argv: list[str] | None = None) -> None:
    import ikdp_viz.app
    from ikdp_viz.__main__ import main as viewer

    apps: list = []
    made = ikdp_viz.app.VizApp

    class KeptApp(made):  # the viewer imports VizApp when it starts: this is the one it makes
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            apps.append(self)
            # read stdin only once there is a viewer to answer for: `--help` never waits on it or stops on its end
            threading.Thread(target=answer, args=(apps,), daemon=True).start()

    ikdp_viz.app.VizApp = KeptApp
    viewer(argv)


if __name__ == "__main__":
    main()
