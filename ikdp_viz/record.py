"""Share a denoising: one self-contained HTML file of a solve, playable and scrubbable offline, no server.

    python -m ikdp_viz.record --output denoising.html                       # ikdp_n4, its first target
    python -m ikdp_viz.record --ckpt ikdp_n8 --target 1.5 2.0 --seed 7 --output n8.html
    python -m ikdp_viz.record --ckpt ikdp_panda --sampler ddpm --output panda.html

The viewer's own arm view draws the solve, state by state, from the viewer's frames, on a private viser server
that no browser connects to, while viser's scene serializer (`server.get_scene_serializer()`)
records every scene message with the time it would be shown: each state after the one
before by the viewer's clock (frame.py, spaced by noise level unless asked otherwise). The
recording goes into viser's static client (`serializer.as_html()`, the whole page in one
file) with a play / pause button, a time slider to scrub and the playback speed. The panel
is not recorded (viser records the scene only), so a label in the scene says the step and the
legend is laid over the page.
The viewer's "Share this denoising" button writes the solve on screen the same way.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ikdp_viz.frame import CLOCK_CHOICES, ViewSettings, state_offsets
from ikdp_viz.planar_scene import TRAIL_CHOICES
from ikdp_viz.style import legend_html

PROGRAM = "python -m ikdp_viz.record"  # the usage line names the module, as a user types it
SHORTEST_STATE = 1 / 60  # seconds each state lasts at least in a recording, so the slider can reach each one
HOLD_FINAL = 1.5  # seconds the final pose stays before the recording loops


RecordSettings = ViewSettings  # how a recording looks: the viewer's view settings (frame.py)


def file_name(solved) -> str:
    """A name that says what was solved: ikdp_ddpm_K16_seed3_+1.900_+1.500.html (a robot: the position in m)."""
    request = solved.request
    where = "_".join(f"{value:+.3f}" for value in request.target[:3])
    return f"ikdp_{request.sampler}_K{request.num_samples}_seed{request.seed}_{where}.html"


def step_text(frame, target_words: str) -> str:
    """The label over the scene: the step and the diffusion time of the frame, the target."""
    return f"IKDP reverse diffusion, {frame.step_label}; {target_words}"


def record_html(solved, settings: ViewSettings | None = None) -> str:
    """The HTML page of `solved` (solving.Solved) denoising from t = T to 0, drawn as the viewer draws it.

    The arm view draws each state from the same `Frame` the viewer builds (frame.py), on a private
    server; the target is the view's own marker (its gizmo hidden: no second marker), the
    step label sits where the camera sees it for both arms, and the legend of the frame's
    colours is laid over the page's corner (a recording has no panel to explain them); viser's
    software-WebGL toast is not shown.
    """
    import viser

    from ikdp_viz.arm_kinds import arm_kind, arm_view
    from ikdp_viz.camera import camera_over, move_cameras
    from ikdp_viz.frame import Palettes, build_frame, solve_noise_levels

    settings = dataclasses.replace(ViewSettings() if settings is None else settings, recording=True)  # its legend
    if settings.seconds <= 0:
        raise ValueError(f"settings.seconds: expected a positive duration, got {settings.seconds}")
    solver, view, kind = solved.request.solver, solved.view, arm_kind(solved.request.solver)
    with contextlib.redirect_stdout(io.StringIO()):  # viser's banner
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        server.scene.configure_environment_map(hdri=None)
        server.scene.configure_default_lights(cast_shadow=False)
        nodes = arm_view(server, solver, solved.request.target, lambda _: None)
        camera = nodes.camera() or camera_over([nodes.extent()])
        move_cameras(server, tuple(tuple(float(value) for value in part) for part in camera))  # recorded
        nodes.aim_cross(np.asarray(camera[0], dtype=np.float64))
        nodes.hide_target_controls()
        serializer = server.get_scene_serializer()
        palettes = Palettes()
        frames = [build_frame(kind, solved, state, settings, palettes=palettes, animating_to=None)
                  for state in range(view.num_states)]  # fmt: skip
        sigmas = solve_noise_levels(solver, view)
        offsets = state_offsets(sigmas, settings.clock, settings.seconds)
        words = kind.target_words(solved.request.target, solver.arm)
        nodes.update(frames[0])
        label = server.scene.add_label("/recording/step", step_text(frames[0], words),
                                       position=label_position(nodes), anchor="top-center")  # fmt: skip
        for state in range(1, view.num_states):
            serializer.insert_sleep(float(max(offsets[state] - offsets[state - 1], SHORTEST_STATE)))
            nodes.update(frames[state])
            label.text = step_text(frames[state], words)
        serializer.insert_sleep(HOLD_FINAL)
        return with_legend(serializer.as_html(), frames[-1].legend)
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def label_position(arm_view) -> tuple[float, float, float]:
    """Where the step label is in view: above the planar arm's circle, or over a robot's reach ball as its camera
    sees it (1.1 reach above the ball's centre was outside the view: the Panda's page showed no label)."""
    camera = arm_view.camera()
    if camera is None:
        return 0.0, 1.1 * arm_view.reach, 0.0
    center = np.asarray(camera[1], dtype=np.float64)
    return float(center[0]), float(center[1]), float(center[2] + 0.55 * arm_view.reach)


def with_legend(page: str, entries) -> str:
    """`page` (viser's static client) with the legend in a box at its bottom left, above the playback bar (at the
    page's foot it covered the bar's time field), and no notification toasts:
    a recording has nothing to notify, and the software-WebGL one covered the scene."""
    box = (
        '<div id="ikdp-legend" style="position:fixed;left:12px;bottom:52px;z-index:1000;background:rgba(255,255,255,'
        '0.88);padding:6px 10px;border-radius:6px;font-family:sans-serif;max-width:340px">'
        + legend_html(list(entries)) + "</div>"
    )  # fmt: skip
    style = "<style>.mantine-Notifications-root { display: none !important; }</style>"
    return page.replace("</body>", style + box + "</body>", 1) if "</body>" in page else page + style + box


@dataclass(frozen=True)
class RecordConfig:
    """Write one self-contained HTML file of a solve's denoising, playable offline with no server."""

    output: Path  # the HTML file to write
    ckpt: str = "ikdp_n4"  # a shipped model's name or a checkpoint's path
    # planar X Y; a robot X Y Z in metres, then ROLL PITCH YAW in degrees or W X Y Z; None: the model's first
    target: tuple[float, ...] | None = None
    samples: int = 16  # samples K
    sampler: str | None = None  # ddpm, ddim, dpmpp2m, student (None: the viewer's default for the model)
    steps: int | None = None  # steps of a sampler that can skip some (None: the viewer's default)
    seed: int = 0  # sampling seed
    refine_steps: int = 0  # damped-least-squares steps after sampling
    highlight: str = "best"  # the sample followed: "best" or its number from 1
    trail_of: str = TRAIL_CHOICES[0]  # highlighted or "all samples"
    show_estimate: bool = False  # ghost x̂0
    clock: str = CLOCK_CHOICES[0]  # noise level or step
    seconds: float = 4.0  # from t = T to 0


def main(argv: list[str] | None = None) -> None:
    import threading
    import time

    import torch
    import tyro

    from ikdp.samplers import SAMPLERS
    from ikdp.shipped import shipped_dir
    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.models import (
        check_viewer_packages,
        checkpoint_path,
        command_target,
        fail,
        load_solver,
        target_flag_error,
    )

    config = tyro.cli(RecordConfig, args=argv, prog=PROGRAM, description=RecordConfig.__doc__)
    check_viewer_packages(PROGRAM)  # before the modules that import viser
    from ikdp_viz.solving import Session, SolveRequest, solve
    from ikdp_viz.student import STUDENT, model_and_student, opening_sampler

    torch.set_num_threads(1)
    solver = load_solver(PROGRAM, checkpoint_path(config.ckpt))
    opened = solver
    solver, student = model_and_student(solver, shipped_dir())  # as the viewer opens the model
    default_sampler, default_steps = opening_sampler(arm_kind(solver), student, student is opened)
    sampler = config.sampler or default_sampler
    if sampler not in (*SAMPLERS, STUDENT):
        fail(PROGRAM, f"--sampler {sampler}: expected one of {', '.join((*SAMPLERS, STUDENT))}")
    if sampler == STUDENT and student is None:
        fail(PROGRAM, f"--sampler student: no distilled student of {config.ckpt} among the shipped models")
    if not config.seconds > 0:
        fail(PROGRAM, f"--seconds {config.seconds}: expected a positive duration")
    try:
        target = command_target(solver, config.target) if config.target is not None else None
    except ValueError as error:
        fail(PROGRAM, target_flag_error(config.target, error))
    runs_on, sampler, steps = Session(solver, student=student).sampling(sampler, config.steps or default_steps)
    request = SolveRequest(
        solver=runs_on, target=arm_kind(solver).initial_target(solver, target), num_samples=config.samples,
        sampler=sampler, steps=steps, refine_steps=config.refine_steps, seed=config.seed,
        arrival=time.perf_counter(), animate=False, student=student, teacher=None if runs_on is solver else solver,
    )  # fmt: skip
    solved = solve(request, threading.Event())
    settings = ViewSettings(
        highlight=config.highlight, trail_of=config.trail_of, show_estimate=config.show_estimate,
        clock=config.clock, seconds=config.seconds,
        show_trail=arm_kind(solver).opens_with_trail,  # as the viewer opens
    )  # fmt: skip
    try:
        config.output.parent.mkdir(parents=True, exist_ok=True)
        config.output.write_text(record_html(solved, settings), encoding="utf-8")
    except OSError as error:
        fail(PROGRAM, f"--output {config.output}: cannot write it ({error.strerror or error})")
    size = config.output.stat().st_size / 1e6
    print(f"wrote {config.output} ({size:.1f} MB): open it in a browser, no server needed")


if __name__ == "__main__":
    main()
