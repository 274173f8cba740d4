"""Share a denoising: one self-contained HTML file of a solve, playable and scrubbable offline, no server.

    python -m ikdp_viz.record --output denoising.html                       # ikdp_n4, its first target
    python -m ikdp_viz.record --ckpt ikdp_n8 --target 1.5 2.0 --seed 7 --output n8.html
    python -m ikdp_viz.record --ckpt ikdp_panda --sampler ddpm --output panda.html

The viewer's own scene writer draws the solve, state by state, on a private viser server
that no browser connects to, while viser's scene serializer (`server.get_scene_serializer()`)
records every scene message with the time it would be shown: each state after the one
before by the viewer's clock (clock.py, spaced by noise level unless asked otherwise). The
recording goes into viser's static client (`serializer.as_html()`, the whole page in one
file) with a play / pause button, a time slider to scrub and the playback speed. The panel
is not recorded (viser records the scene only), so a label in the scene says the step.
The viewer's "Share this denoising" button writes the solve on screen the same way.
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ikdp_viz.clock import CLOCK_CHOICES, state_offsets
from ikdp_viz.emphasis import TRAIL_CHOICES

PROGRAM = "python -m ikdp_viz.record"  # the usage line names the module, as a user types it
SHORTEST_STATE = 1 / 60  # seconds each state lasts at least in a recording, so the slider can reach each one
HOLD_FINAL = 1.5  # seconds the final pose stays before the recording loops


@dataclass(frozen=True)
class RecordSettings:
    """How the recording looks: the viewer's view settings, as its panel holds them."""

    highlight: str = "best"  # the highlight dropdown: "best" or a sample's number from 1
    trail_of: str = TRAIL_CHOICES[0]  # highlighted (the paper's figure) or all samples
    show_trail: bool = True  # the trail up to the step shown
    show_estimate: bool = False  # ghost x̂0
    clock: str = CLOCK_CHOICES[0]  # spacing of the states in time: noise level or step
    seconds: float = 4.0  # from t = T to 0

    @classmethod
    def from_panel(cls, panel) -> RecordSettings:
        return cls(
            highlight=str(panel.highlight.value), trail_of=str(panel.learn.trail_of.value),
            show_trail=bool(panel.show_trail.value), show_estimate=bool(panel.show_estimate.value),
            clock=str(panel.learn.clock.value), seconds=float(panel.duration.value) or 4.0,
        )  # fmt: skip


def file_name(solved) -> str:
    """A name that says what was solved: ikdp_ddpm_K16_seed3_+1.900_+1.500.html (a robot: the position in m)."""
    request = solved.request
    where = "_".join(f"{value:+.3f}" for value in request.target[:3])
    return f"ikdp_{request.sampler}_K{request.num_samples}_seed{request.seed}_{where}.html"


def step_text(view, state: int, target_text: str) -> str:
    """The label over the scene: the step, the diffusion time, the highlighted sample's tip error."""
    last = view.num_states - 1
    return f"IKDP reverse diffusion, step {state} of {last} (t = {int(view.labels[state])}); {target_text}"


def record_html(solved, settings: RecordSettings = RecordSettings()) -> str:
    """The HTML page of `solved` (solving.Solved) denoising from t = T to 0, drawn as the viewer draws it."""
    import viser

    from ikdp_viz.chain_scene_writer import scene_writer_class
    from ikdp_viz.panel import build_panel

    if settings.seconds <= 0:
        raise ValueError(f"settings.seconds: expected a positive duration, got {settings.seconds}")
    solver, view = solved.request.solver, solved.view
    with contextlib.redirect_stdout(io.StringIO()):  # viser's banner
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        panel = build_panel(
            server.gui, num_timesteps=solver.timesteps, animation_seconds=settings.seconds, sampler_names=("ddpm",),
            checkpoint_labels=("model",), checkpoint_label="model", model_text="",
        )  # fmt: skip
        panel.highlight.options = ("best", *(str(number) for number in range(1, view.num_samples + 1)))
        panel.highlight.value = settings.highlight
        panel.learn.trail_of.value, panel.learn.clock.value = settings.trail_of, settings.clock
        panel.show_trail.value, panel.show_estimate.value = settings.show_trail, settings.show_estimate
        writer = scene_writer_class(solver)(server, panel, solver, solved.request.target, lambda _: None)
        serializer = server.get_scene_serializer()
        camera = server.initial_camera
        camera.position, camera.look_at = (
            tuple(map(float, camera.position)),
            tuple(map(float, camera.look_at)),
        )  # recorded
        target_text = mark_target(server, writer, solved.request.target)
        writer.draw_recorded_state(solved, 0)
        offsets = state_offsets(writer.noise_levels(), settings.clock, settings.seconds)
        label = server.scene.add_label(
            "/recording/step", step_text(view, 0, target_text), position=label_position(writer), anchor="top-center"
        )
        for state in range(1, view.num_states):
            serializer.insert_sleep(float(max(offsets[state] - offsets[state - 1], SHORTEST_STATE)))
            writer.draw_recorded_state(solved, state)
            label.text = step_text(view, state, target_text)
        serializer.insert_sleep(HOLD_FINAL)
        return serializer.as_html()
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def mark_target(server, writer, target: np.ndarray) -> str:
    """The target drawn without its gizmo (no one can drag it in a recording); returns its text for the label."""
    from ikdp_viz import meshes
    from ikdp_viz.scene_writer import TARGET_RED

    writer.gizmo.visible = False
    if len(target) == 2:
        cross = meshes.cross_mesh(writer.sizes.cross)
        server.scene.add_mesh_simple(
            "/recording/target", cross.vertices, cross.faces, color=TARGET_RED, cast_shadow=False,
            receive_shadow=False, position=(float(target[0]), float(target[1]), float(writer.cross.position[2])),
        )  # fmt: skip
        return f"target x = {target[0]:+.3f}, y = {target[1]:+.3f}"
    wxyz = target[3:7] if len(target) == 7 else (1.0, 0.0, 0.0, 0.0)
    server.scene.add_frame(
        "/recording/target", axes_length=0.1 * writer.reach, axes_radius=0.006 * writer.reach,
        position=tuple(float(value) for value in target[:3]), wxyz=tuple(float(value) for value in wxyz),
    )  # fmt: skip
    x, y, z = 1000 * np.asarray(target[:3])
    return f"target x = {x:+.0f}, y = {y:+.0f}, z = {z:+.0f} mm"


def label_position(writer) -> tuple[float, float, float]:
    """Above the workspace: the top of the planar arm's circle, or above the robot's reach ball."""
    if hasattr(writer, "reach"):
        center = writer.solver.arm.reach_center.double().numpy()
        return float(center[0]), float(center[1]), float(center[2] + 1.1 * writer.reach)
    return 0.0, 1.1 * float(writer.solver.reach[1]), 0.0


@dataclass(frozen=True)
class RecordConfig:
    """Write one self-contained HTML file of a solve's denoising, playable offline with no server."""

    output: Path  # the HTML file to write
    ckpt: str = "ikdp_n4"  # a shipped model's name or a checkpoint's path
    # planar X Y; a robot X Y Z in metres, then ROLL PITCH YAW in degrees or W X Y Z; None: the model's first
    target: tuple[float, ...] | None = None
    samples: int = 16  # samples K
    sampler: str | None = None  # ddpm, ddim, dpmpp2m (None: the viewer's default for the model)
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
    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.command_line import checkpoint_path, command_target, fail, load_solver, target_flag_error
    from ikdp_viz.solving import SolveRequest, solve

    config = tyro.cli(RecordConfig, args=argv, prog=PROGRAM, description=RecordConfig.__doc__)
    torch.set_num_threads(1)
    solver = load_solver(PROGRAM, checkpoint_path(config.ckpt))
    default_sampler, default_steps = arm_kind(solver).default_sampler
    sampler = config.sampler or default_sampler
    if sampler not in SAMPLERS:
        fail(PROGRAM, f"--sampler {sampler}: expected one of {', '.join(SAMPLERS)}")
    if not config.seconds > 0:
        fail(PROGRAM, f"--seconds {config.seconds}: expected a positive duration")
    try:
        target = command_target(solver, config.target) if config.target is not None else None
    except ValueError as error:
        fail(PROGRAM, target_flag_error(config.target, error))
    steps = (config.steps or default_steps) if SAMPLERS[sampler].supports_steps else None
    request = SolveRequest(
        solver=solver, target=arm_kind(solver).initial_target(solver, target), num_samples=config.samples,
        sampler=sampler, steps=steps, refine_steps=config.refine_steps, seed=config.seed,
        arrival=time.perf_counter(), animate=False,
    )  # fmt: skip
    solved = solve(request, threading.Event())
    settings = RecordSettings(
        highlight=config.highlight, trail_of=config.trail_of, show_estimate=config.show_estimate,
        clock=config.clock, seconds=config.seconds,
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
