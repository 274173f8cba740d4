"""Command line of the IKDP viewer: start a viser server and print the URL to open.

    python -m ikdp_viz                                   # the shipped ikdp_n4
    python -m ikdp_viz --ckpt ikdp_n8 --port 8081        # another shipped model, or a checkpoint's path
    python -m ikdp_viz --ckpt checkpoints/ikdp_panda.pt  # a robot (URDF): meshes, 6-DoF gizmo at the hand
    python -m ikdp_viz --host 0.0.0.0                    # let other machines connect
    python -m ikdp_viz --target -0.01 1.2 --seed 0 --sampler ddim --steps 10   # reproduce what you saw
    python -m ikdp_viz --ckpt ikdp_panda --target 0.5 0.1 0.4 180 0 0   # a robot: x y z (m), roll pitch yaw (deg)

A checkpoint that cannot be used, a port outside 0..65535 or a host that cannot
be listened on is a one-line error and exit status 2;
Ctrl-C stops the server cleanly.
"""

from __future__ import annotations

import contextlib
import io
import signal
import socket
import sys
import time
from dataclasses import dataclass

from ikdp.shipped import DEFAULT_MODEL, shipped_dir
from ikdp_viz import models
from ikdp_viz.models import check_viewer_packages, checkpoint_path, command_target, target_flag_error

PROGRAM = "ikdp-viz"
SIGNAL_CHECK_SECONDS = 0.2  # how late Ctrl-C may be noticed at most


@dataclass(frozen=True)
class VizConfig:
    """Interactive browser view of IKDP's reverse diffusion: drag the target, watch the arm denoise."""

    ckpt: str = DEFAULT_MODEL  # a shipped model's name (see the Model panel) or the path of a checkpoint file
    host: str = "127.0.0.1"  # address to listen on; 0.0.0.0 lets other machines connect
    port: int = 8080  # port to listen on; if taken, the next free one
    device: str = "cpu"  # torch device the model runs on: cpu, cuda, cuda:1, ...
    # the first target (None: the arm's own): planar X Y; a robot X Y Z in metres, then ROLL PITCH YAW in degrees
    # or W X Y Z (a pose model given X Y Z keeps its first rotation); to open on what you saw, for a bug report
    target: tuple[float, ...] | None = None
    samples: int = 16  # samples K, 1 to 64
    # ddpm, ddim, dpmpp2m, or student: the distilled few-step student folded into the model's file (None: the
    # student for a robot that has one, else ddpm)
    sampler: str | None = None
    steps: int | None = None  # reverse steps of a sampler that can skip some, not ddpm (None: 20; 10 for a robot)
    seed: int = 0  # sampling seed
    refine_steps: int = 0  # damped-least-squares steps after sampling; 0: none
    # open on the guided first visit, six steps (a planar arm's; its steps set K, the sampler and the view);
    # --no-tour opens the viewer as the flags set it
    tour: bool = True


def parse_config(argv: list[str] | None = None) -> VizConfig:
    import tyro  # here: importing this module does nothing

    return tyro.cli(VizConfig, args=argv, prog=PROGRAM, description=VizConfig.__doc__)


def check_settings(config: VizConfig) -> None:
    """Exit 2 with one line for a sampling setting the panel cannot show."""
    from ikdp.samplers import SAMPLERS
    from ikdp_viz.panel import MAX_SAMPLES
    from ikdp_viz.student import STUDENT

    if config.sampler is not None and config.sampler not in (*SAMPLERS, STUDENT):
        fail(f"--sampler {config.sampler}: expected one of {', '.join((*SAMPLERS, STUDENT))}")
    for name, value, low, high in (
        ("samples", config.samples, 1, MAX_SAMPLES),
        ("steps", 1 if config.steps is None else config.steps, 1, 10_000),
        ("refine-steps", config.refine_steps, 0, 50),
        ("seed", config.seed, 0, 2**31 - 1),
    ):
        if not low <= value <= high:
            fail(f"--{name} {value}: expected {low} to {high}")  # fmt: skip


def apply_settings(app, config: VizConfig) -> None:
    """Set the panel as the flags ask, then solve the first target."""
    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.student import STUDENT, opening_sampler

    panel = app.panel
    default_sampler, default_steps = opening_sampler(arm_kind(app.solver), app.session.student, app.asked_for_student)
    if config.sampler == STUDENT and app.session.student is None:
        fail(f"--sampler student: {app.solver.metadata['path']} holds no distilled student")
    panel.samples.value = config.samples
    panel.sampler.value = config.sampler or default_sampler
    panel.steps.value = min(default_steps if config.steps is None else config.steps, panel.steps.max)
    panel.seed.value = config.seed
    if config.refine_steps:
        panel.refine_steps.value = config.refine_steps
        panel.refine.value = True
    app.move_target(app.target if config.target is None else config_target(app.solver, config))


def config_target(solver, config: VizConfig):
    """The target `--target` asks for; ValueError when its numbers do not make one for this arm."""
    return command_target(solver, config.target)


def fail(message: str) -> None:
    models.fail(PROGRAM, message)


def check_address(host: str, port: int) -> None:
    """Exit 2 with one line for a port outside 0..65535 or a host this machine cannot listen on.

    viser would raise OverflowError in its own thread for the first and hang; a taken port is
    fine (viser moves to the next), so the host is tried on a free port.
    """
    if not 0 <= port <= 65535:
        fail(f"--port {port}: expected a port from 0 to 65535 (0: any free one)")
    try:
        family = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)[0][0]
        with socket.socket(family, socket.SOCK_STREAM) as probe:
            probe.bind((host, 0))
    except (OSError, UnicodeError) as error:
        fail(f"--host {host}: cannot listen there ({getattr(error, 'strerror', None) or error})")


def main(argv: list[str] | None = None) -> None:
    config = parse_config(argv)
    check_viewer_packages(PROGRAM)
    check_address(config.host, config.port)
    check_settings(config)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # a kill stops as cleanly as Ctrl-C
    # Started with SIGINT ignored (`nohup ... &`, a CI runner), Python installs no Ctrl-C handler: install it
    signal.signal(signal.SIGINT, signal.default_int_handler)
    server = app = None
    try:
        path = checkpoint_path(config.ckpt)
        solver = models.load_solver(PROGRAM, path, config.device)
        from ikdp_viz.arm_kinds import arm_kind

        try:
            arm_kind(solver)  # an arm the views cannot draw is refused before the server starts
        except ValueError as error:
            fail(f"--ckpt {config.ckpt}: {error}")
        if config.target is not None:
            try:
                config_target(solver, config)
            except ValueError as error:
                fail(target_flag_error(config.target, error))

        import torch
        import viser

        from ikdp_viz.app import VizApp, list_checkpoints

        torch.set_num_threads(1)  # one small solve at a time: more threads only spin against each other
        with contextlib.redirect_stdout(io.StringIO()):  # viser's own banner; the URL is printed below
            server = viser.ViserServer(host=config.host, port=config.port, verbose=False)
        app = VizApp(
            server,
            solver,
            checkpoints=list_checkpoints(shipped_dir(), path),
            checkpoint_folder=shipped_dir(),
            solve_now=False,
            wait_for_tab=True,  # the first solve waits at pure noise and plays when the first tab opens
        )
        apply_settings(app, config)
        if config.tour:
            app.tour.start()
        port = server.get_port()
        shown_host = "localhost" if config.host in ("0.0.0.0", "::", "") else config.host
        print(f"ikdp-viz: open http://{shown_host}:{port}", flush=True)
        details = f"model {path} (N={solver.num_links}, T={solver.timesteps}); Ctrl-C to stop"
        if port != config.port:
            details = f"port {config.port} was taken, using {port}; " + details
        if config.host in ("0.0.0.0", "::"):
            details = "listening on all interfaces; " + details
        print(f"ikdp-viz: {details}", flush=True)
        # viser's own address parameter: half-resolution drawing, about 1.5 times the frames in
        # software WebGL (docs/viewer.md, "Frames in the page")
        print(
            f"ikdp-viz: a slow page (no GPU)? http://{shown_host}:{port}/?fixedDpr=0.5 draws at half resolution",
            flush=True,
        )
        # Short naps, not one long sleep: Ctrl-C can land on one of viser's or torch's threads, and Python
        # then only raises KeyboardInterrupt here once this thread wakes (2 of 25 stops under load hung).
        while True:
            time.sleep(SIGNAL_CHECK_SECONDS)
    except KeyboardInterrupt:
        pass
    finally:
        if app is not None:
            app.close()
        if server is not None:
            server.stop()
    print("ikdp-viz: stopped", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
