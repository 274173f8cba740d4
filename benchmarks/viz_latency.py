"""Viewer latency: gizmo updates at 20 Hz for 30 s, time from each update's arrival to the scene update.

Run from the repository root:

    python -m benchmarks.viz_latency                    # the full protocol, about 45 s
    python -m benchmarks.viz_latency --seconds 5        # a smoke run

Setup, as a user meets the app: the default checkpoint (N=4), K=16 samples,
80-step DDPM with the trajectory, the animation on (1 s), one connected client.
The client is a plain websocket that receives and discards everything, so the
server serialises and sends every frame while no browser rendering competes for
the two cores. Gizmo updates go through the app's gizmo callback on viser's
event loop, exactly where a browser's drag message lands after decoding; the
target moves along a smooth closed curve inside the workspace.

Measured:
  1. latency of an update drawn as the newest target: its arrival (callback
     entry) to the end of the `server.atomic()` block that puts its solve on
     screen (solves drawn after a newer update arrived are counted apart);
  2. latency of every update: its arrival to the first scene update for a target
     at least as new (a superseded update is served by a newer one);
  3. the backlog: updates replaced before they started or cancelled part-way, and
     the latency in the first and last thirds of the run (a growing backlog
     would show as growing latency);
  4. responsiveness: how late the event loop runs a probe scheduled every 100 ms;
  5. the process's resident memory after warm-up and after the run.
Results go to benchmarks/results/viz_latency.json.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import gc
import io
import json
import math
import os
import platform
import shlex
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import torch
import viser
from websockets.sync.client import connect

import ikdp
from ikdp.evaluation.machine import cpu_model
from ikdp.shipped import DEFAULT_MODEL, shipped_checkpoint
from ikdp_viz.app import VizApp


def resident_megabytes() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def percentiles(values_ms: list[float]) -> dict[str, float]:
    if not values_ms:
        return {"count": 0}
    values = np.asarray(values_ms)
    return {
        "count": len(values),
        "median_ms": round(float(np.median(values)), 2),
        "p95_ms": round(float(np.percentile(values, 95)), 2),
        "p99_ms": round(float(np.percentile(values, 99)), 2),
        "max_ms": round(float(values.max()), 2),
    }


def path_point(time_s: float, outer: float) -> tuple[float, float]:
    """A smooth closed curve inside the workspace: radius 0.3..0.85 of the reach, one turn per 6 s."""
    angle = 2 * math.pi * time_s / 6.0
    radius = outer * (0.575 + 0.275 * math.sin(3.1 * angle))
    return radius * math.cos(angle), radius * math.sin(angle)


class SinkClient:
    """A websocket client of the viser server that reads and discards every message."""

    def __init__(self, port: int):
        self.socket = connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None)
        self.messages = self.bytes = 0
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        with contextlib.suppress(Exception):
            while True:
                message = self.socket.recv()
                self.messages += 1
                self.bytes += len(message)

    def close(self) -> None:
        self.socket.close()
        self.thread.join(5)


def solve_only(solver: ikdp.Solver, repeats: int) -> dict[str, float]:
    times = []
    for index in range(repeats):
        generator = torch.Generator().manual_seed(index)
        started = time.perf_counter()
        solver.solve(
            [path_point(index * 0.37, solver.reach[1])], num_samples=16, generator=generator, return_trajectory=True
        )
        times.append(1000 * (time.perf_counter() - started))
    return percentiles(times)


class Stream:
    """Gizmo updates into the app at a fixed rate, through its callback on viser's event loop."""

    def __init__(self, app: VizApp, client: SinkClient):
        self.app, self.client = app, client
        self.loop = app.server.get_event_loop()
        self.arrivals: list[float] = []
        self.frames = 0
        writer = app.writer
        draw = writer._draw_state

        def counting_draw(state: int) -> None:
            self.frames += 1
            draw(state)

        writer._draw_state = counting_draw  # count the frames written (on the scene writer's thread)

    def send(self, point, phase: str) -> None:
        """What viser does with a decoded drag message: set the gizmo's pose, run its callback on the loop."""
        app = self.app

        async def deliver():
            self.arrivals.append(time.perf_counter())
            gizmo = app.gizmo
            gizmo._impl.position = np.array([point[0], point[1], 0.0])  # as viser's handler does
            event = viser.TransformControlsEvent(client=None, client_id=None, target=gizmo, phase=phase)
            await app.on_gizmo_update(event)

        asyncio.run_coroutine_threadsafe(deliver(), self.loop)

    def run(self, *, rate: float, seconds: float, phase: str) -> dict:
        app, client, outer = self.app, self.client, self.app.solver.reach[1]
        self.arrivals.clear()
        app.latencies.clear()
        self.frames = 0
        stats_before = dict(vars(app.worker.stats))
        sent_before = (client.messages, client.bytes)
        loop_lags: list[float] = []
        stop = threading.Event()

        def probe() -> None:
            while not stop.is_set():
                scheduled = time.perf_counter()

                async def note(scheduled=scheduled):
                    loop_lags.append(1000 * (time.perf_counter() - scheduled))

                asyncio.run_coroutine_threadsafe(note(), self.loop)
                stop.wait(0.1)

        prober = threading.Thread(target=probe, daemon=True)
        prober.start()
        started = time.perf_counter()
        count = int(seconds * rate)
        for index in range(count):
            time.sleep(max(0.0, started + index / rate - time.perf_counter()))
            self.send(path_point(index / rate, outer), phase)
        last_sent = time.perf_counter()
        time.sleep(0.2)
        app.wait_until_still(60)
        stop.set()
        prober.join()
        duration = time.perf_counter() - started

        # 1. updates drawn as the newest target; those a newer update overtook during their solve apart;
        # 2. every update, served by the first drawing of a target at least as new
        drawn = sorted(app.latencies)
        newest_ms = [1000 * (shown - arrival) for arrival, shown, newest in drawn if newest]
        late_ms = [1000 * (shown - arrival) for arrival, shown, newest in drawn if not newest]
        drawn_arrivals = np.array([arrival for arrival, _, _ in drawn])
        every_ms = []
        for arrival in sorted(self.arrivals):
            index = int(np.searchsorted(drawn_arrivals, arrival))
            if index < len(drawn):
                every_ms.append(1000 * (drawn[index][1] - arrival))
        thirds = np.array_split(np.array(newest_ms), 3)
        last_drawn = max((shown for _, shown, _ in drawn), default=last_sent)
        return {
            "drawn_update_latency": percentiles(newest_ms),
            "late_drawn_latency": percentiles(late_ms),
            "every_update_latency": percentiles(every_ms),
            "latency_by_third_median_ms": [round(float(np.median(part)), 2) for part in thirds if len(part)],
            "drain_ms": round(1000 * max(0.0, last_drawn - last_sent), 1),  # last update sent -> last scene update
            "updates_sent": count,
            "updates_arrived": len(self.arrivals),
            "worker": {key: value - stats_before[key] for key, value in vars(app.worker.stats).items()},
            "frames_written": self.frames,
            "client_messages": client.messages - sent_before[0],
            "client_megabytes": round((client.bytes - sent_before[1]) / 2**20, 1),
            "event_loop_lag": percentiles(loop_lags),
            "run_seconds": round(duration, 2),
        }


PHASES = {
    "drag": ("update", "a drag: every update a drag update; each solve drawn at its final pose, no animation"),
    "moves": ("end", "separate moves: every update a finished move; each solve animated from t=T (1 s), restarted"),
}


def print_table(name: str, result: dict, solve_alone: dict) -> None:
    print(f"\n[{name}] {PHASES[name][1]}")
    print(f"{'':34}{'median':>9}{'p95':>9}{'p99':>9}{'max':>9}{'count':>7}")
    for label, row in (
        ("arrival -> its scene update", result["drawn_update_latency"]),
        ("  (drawn though a newer one came)", result["late_drawn_latency"]),
        ("arrival -> newest scene update", result["every_update_latency"]),
        ("solve alone", solve_alone),
        ("event loop lag", result["event_loop_lag"]),
    ):
        if not row["count"]:
            print(f"{label:34}{'-':>9}{'-':>9}{'-':>9}{'-':>9}{0:7d}")
            continue
        numbers = "".join(f"{row[key]:9.1f}" for key in ("median_ms", "p95_ms", "p99_ms", "max_ms"))
        print(f"{label:34}{numbers}{row['count']:7d}")
    print(f"worker: {result['worker']}")
    print(f"frames written {result['frames_written']}, {result['client_megabytes']} MB sent to the client")
    print(
        f"latency by third of the run (median ms): {result['latency_by_third_median_ms']}; "
        f"last update to last scene update: {result['drain_ms']} ms"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--ckpt", default=str(shipped_checkpoint(DEFAULT_MODEL)), help="checkpoint (the shipped N=4 model)"
    )
    parser.add_argument("--rate", type=float, default=20.0, help="gizmo updates per second")
    parser.add_argument("--seconds", type=float, default=30.0, help="length of each run")
    parser.add_argument("--animation", type=float, default=1.0, help="animation duration (s), the app's default")
    parser.add_argument("--output", default="benchmarks/results/viz_latency.json")
    parser.add_argument("--label", default="latest", help="name of this run in the JSON (other labels are kept)")
    parser.add_argument("--stale-grace", type=float, default=None, help="override the worker's stale grace (s)")
    parser.add_argument("--cancel-fraction", type=float, default=None, help="override the worker's cancel fraction")
    args = parser.parse_args(argv)
    command_line = sys.argv[1:] if argv is None else argv

    torch.set_num_threads(1)  # as the CLI runs it
    load_at_start = os.getloadavg()
    solver = ikdp.load(args.ckpt)
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = VizApp(server, solver, animation_seconds=args.animation)
    if args.stale_grace is not None:
        app.worker.stale_grace = args.stale_grace
    if args.cancel_fraction is not None:
        app.worker.cancel_fraction = args.cancel_fraction
    client = SinkClient(server.get_port())
    stream = Stream(app, client)

    for phase, _ in PHASES.values():  # warm-up: two seconds of each kind of traffic
        stream.run(rate=args.rate, seconds=2.0, phase=phase)
    solve_alone = solve_only(solver, 40)
    gc.collect()
    memory_before = resident_megabytes()
    results = {
        name: stream.run(rate=args.rate, seconds=args.seconds, phase=phase) for name, (phase, _) in PHASES.items()
    }
    gc.collect()
    time.sleep(0.5)
    memory_after = resident_megabytes()
    memory = {
        "before": round(memory_before, 1),
        "after": round(memory_after, 1),
        "growth": round(memory_after - memory_before, 1),
    }

    def no_backlog(result: dict) -> bool:
        """Nothing left to catch up on: the last update is on screen within two slow solves of being sent."""
        return result["drain_ms"] <= 2 * solve_alone["p95_ms"] + 50

    targets = {
        **{
            f"{name}_newest_drawn_p95_le_50ms": result["drawn_update_latency"]["p95_ms"] <= 50
            for name, result in results.items()
        },
        **{
            f"{name}_every_update_p95_le_50ms": result["every_update_latency"]["p95_ms"] <= 50
            for name, result in results.items()
        },
        "memory_growth_le_50mb": memory["growth"] <= 50,
        "no_backlog": all(no_backlog(result) for result in results.values()),
    }
    record = {
        "setup": {
            "checkpoint": args.ckpt,
            "num_links": solver.num_links,
            "timesteps": solver.timesteps,
            "num_samples": 16,
            "sampler": "ddpm, all steps, return_trajectory=True",
            "update_rate_hz": args.rate,
            "seconds_per_run": args.seconds,
            "animation_seconds": args.animation,
            "runs": {name: description for name, (_, description) in PHASES.items()},
            "client": "one websocket client reading and discarding every message",
            "update_path": "app.on_gizmo_update on viser's event loop (a decoded drag message's path)",
            "latency_end": "end of the server.atomic() block that first writes the update's solve",
            "stale_grace_s": app.worker.stale_grace,
            "cancel_fraction": app.worker.cancel_fraction,
            "torch_threads": torch.get_num_threads(),
            "command": shlex.join(["python", "-m", "benchmarks.viz_latency", *command_line]),
        },
        "environment": {
            "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "cpu_model": cpu_model(),
            "logical_cpus": os.cpu_count(),
            "load_average_at_start": round(load_at_start[0], 2),
            "load_average_at_end": round(os.getloadavg()[0], 2),
            "python": platform.python_version(),
            "torch": torch.__version__,
            "viser": viser.__version__,
            "platform": platform.platform(),
        },
        "results": {**results, "solve_alone": solve_alone, "memory_mb": memory},
        "targets_met": targets,
    }
    client.close()
    app.close()
    with contextlib.redirect_stdout(io.StringIO()):
        server.stop()

    print(
        f"viewer latency, {args.rate:g} Hz for {args.seconds:g} s per run, N={solver.num_links} K=16 "
        f"DDPM-{solver.timesteps}, load average {load_at_start[0]:.2f} at start"
    )
    for name, result in results.items():
        print_table(name, result, solve_alone)
    print(f"\nmemory: {memory['before']} MB -> {memory['after']} MB ({memory['growth']:+} MB) over both runs")
    print(f"targets met: {targets}")
    output = Path(args.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    runs = {}
    if output.exists():
        with contextlib.suppress(ValueError, KeyError, TypeError):
            runs = dict(json.loads(output.read_text())["runs"])
    runs[args.label] = record
    output.write_text(json.dumps({"runs": runs}, indent=2) + "\n")
    print(f"wrote {output} (run {args.label!r})")


if __name__ == "__main__":
    main()
