"""The viewer in-process: a real viser server on a free port, driven through its handles' API.

Solves use a tiny 3-link checkpoint; the animation duration is 0 unless a test
plays it, so every check reads a finished frame.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
import torch
from viz_helpers import drag_gizmo, running_app, settle

import ikdp
from ikdp.train import TrainConfig, train
from ikdp_viz.app import list_checkpoints
from ikdp_viz.planar_scene import HIGHLIGHT_LIFT
from ikdp_viz.solve_worker import Cancelled
from ikdp_viz.solving import SolveRequest, solve


@pytest.fixture(scope="module")
def two_link_checkpoint(tmp_path_factory):
    """A second tiny model with another N and T, for the checkpoint switch."""
    folder = tmp_path_factory.mktemp("tiny2")
    config = TrainConfig(
        joints=2, steps=10, batch=32, hidden=16, blocks=1, timesteps=12, eval_targets=0, save_every=1000,
        output=str(folder / "two.pt"), log_dir=str(folder / "tb"), threads=1,
    )  # fmt: skip
    return train(config)


@pytest.fixture
def solver(tiny_checkpoint):
    return ikdp.load(tiny_checkpoint)


@pytest.fixture
def app(solver):
    with running_app(solver, animation_seconds=0.0) as app:
        settle(app)
        yield app


def drawn_joints(app) -> np.ndarray:
    """Joint positions of the solid arms on screen, (K, N+1, 2)."""
    view = app.solved.view
    return app.joints.batched_positions.reshape(view.num_samples, view.num_links + 1, 3)[..., :2]


def final_polylines(app) -> np.ndarray:
    """The last state's polylines in the trail node, (K, N, 2, 2): segment ends per link."""
    view = app.solved.view
    count = view.num_samples * view.num_links
    return app.trail.points[-count:].reshape(view.num_samples, view.num_links, 2, 3)[..., :2]


def test_moving_the_gizmo_solves_the_new_target_and_draws_its_final_pose(app, solver):
    app.panel.learn.trail_of.value = "all samples"  # every final polyline in the trail
    drag_gizmo(app, 1.1, -0.7)
    settle(app)
    view = app.solved.view
    assert np.allclose(view.target, [1.1, -0.7]) and app.state == view.num_states - 1
    assert app.panel.timestep.value == 0
    # the same solve, independently: the app draws what the public API returns for this target and seed
    generator = torch.Generator().manual_seed(int(app.panel.seed.value))
    out = solver.solve([[1.1, -0.7]], num_samples=16, generator=generator, return_trajectory=True)
    tips = final_polylines(app)[:, -1, 1]  # (K, 2) the end of each final polyline
    tip_error = np.linalg.norm(tips - [1.1, -0.7], axis=-1)
    assert np.allclose(tip_error, out.raw_tip_error[0].numpy(), atol=1e-4)  # within the solver's own error
    expected = ikdp.forward_kinematics(out.raw_angles[0].double()).numpy()
    assert np.allclose(drawn_joints(app), expected, atol=1e-4)
    assert app.links.points.shape == (16 * 3, 2, 3) and app.tips.batched_positions.shape == (16, 3)
    assert "x = +1.100, y = -0.700" in app.panel.target_text.content and "Clamped" not in app.panel.target_text.content


def test_scrubbing_the_timestep_slider_shows_that_state(app):
    app.panel.learn.trail_of.value = "all samples"
    view = app.solved.view
    final = drawn_joints(app).copy()
    app.panel.timestep.value = 7
    state = int(np.flatnonzero(view.labels == 7)[0])
    assert app.state == state
    shown = drawn_joints(app)
    assert not np.allclose(shown, final)
    assert np.allclose(shown, view.joints[state], atol=1e-5)
    assert app.trail.points.shape[0] == (state + 1) * view.num_samples * view.num_links
    assert f"**Step** {state} of {view.num_states - 1} (t = 7)" in app.panel.readout_text.content
    t, median, chosen, marker = app.panel.plot.data
    assert np.isfinite(marker).sum() == 1 and t[np.isfinite(marker)][0] == 7
    # the chart runs t = 0 .. T left to right, as the slider does
    x_scale = app.panel.plot.scales["x"]
    assert x_scale.get("dir", 1) == 1 and tuple(x_scale["range"]) == (0.0, app.solver.timesteps)
    assert app.panel.timestep.min == 0 and app.panel.timestep.max == app.solver.timesteps


def test_previous_and_next_buttons_step_through_the_states(app):
    last = app.solved.view.num_states - 1
    app.panel.previous_button.value = True  # what a click does
    assert app.state == last - 1 and app.panel.timestep.value == 1
    app.panel.next_button.value = True
    app.panel.next_button.value = True  # past the end: stays on the final pose
    assert app.state == last and app.panel.timestep.value == 0


def test_a_target_past_the_boundary_is_clamped_and_the_panel_says_so(app, solver):
    drag_gizmo(app, 10.0, 0.0)
    settle(app)
    outer = solver.reach[1]
    assert np.allclose(app.gizmo.position, [outer, 0.0, 0.0])
    assert np.allclose(app.solved.view.target, [outer, 0.0])
    assert "Clamped to the workspace boundary" in app.panel.target_text.content


def test_a_drag_released_past_the_boundary_still_reads_clamped_and_sends_the_cross_to_the_solved_point(app, solver):
    outer = solver.reach[1]
    drag_gizmo(app, 10.0, 0.0)  # mid-drag: the app puts the gizmo on the boundary
    sent = []
    real_queue = app.gizmo._impl.api._queue_scene_message
    app.gizmo._impl.api._queue_scene_message = lambda message: (sent.append(message), real_queue(message))[1]
    try:
        # viser's release event carries the position the app last wrote: the boundary point itself
        drag_gizmo(app, *app.gizmo.position[:2], phase="end")
        settle(app)
    finally:
        app.gizmo._impl.api._queue_scene_message = real_queue
    assert np.allclose(app.solved.view.target, [outer, 0.0])
    assert "Clamped to the workspace boundary" in app.panel.target_text.content
    positions = [message.position for message in sent
                 if type(message).__name__ == "SetPositionMessage" and message.name == app.gizmo.name]  # fmt: skip
    assert positions and np.allclose(positions[-1], [outer, 0.0, 0.0])  # the page's cross is moved there


def test_the_trail_toggle_shows_all_intermediate_poses_or_none(app):
    app.panel.learn.trail_of.value = "all samples"
    view = app.solved.view
    assert app.trail.visible and app.trail.points.shape[0] == view.num_states * view.num_samples * view.num_links
    app.panel.show_trail.value = False
    assert not app.trail.visible and app.links.visible
    app.panel.show_trail.value = True
    assert app.trail.visible


def test_the_default_picture_follows_the_highlighted_sample_as_the_papers_figure(app):
    view, highlight = app.solved.view, app.highlight_index()
    num_samples, num_links = view.num_samples, view.num_links
    assert app.panel.learn.trail_of.value == "highlighted"
    # the trail is the highlighted sample's alone, every state of it, darkening toward t = 0
    assert app.trail.points.shape[0] == view.num_states * num_links
    per_state = app.trail.points.reshape(view.num_states, num_links, 2, 3)[..., :2]
    assert np.allclose(per_state[:, :, 0], view.joints[:, highlight, :-1], atol=1e-5)
    brightness = app.trail.colors.reshape(view.num_states, -1).astype(int).sum(axis=1)
    assert brightness[0] > brightness[-1] and (np.diff(brightness) <= 0).all()
    # the others' final poses light lines, the highlighted one dark blue with its joints; the others' joints not drawn
    from ikdp_viz.planar_scene import line_colors
    from ikdp_viz.style import ACCENT_DARK, OTHERS_FINAL

    link_colors = app.links.colors.reshape(num_samples, num_links, 2, 3)[:, 0, 0]
    others = np.delete(link_colors, highlight, axis=0)
    assert (others == line_colors(np.array(OTHERS_FINAL, np.uint8))).all()  # light grey (185)
    assert (link_colors[highlight] == line_colors(np.array(ACCENT_DARK, np.uint8))).all()
    scales = app.joints.batched_scales.reshape(num_samples, num_links + 1)
    assert (scales[highlight] == 1).all() and (np.delete(scales, highlight, axis=0) == 0).all()
    assert (app.joints.batched_colors.reshape(num_samples, -1, 3)[highlight] == ACCENT_DARK).all()
    # x̂0 of the followed sample only; all of them with "all samples"
    app.panel.show_estimate.value = True
    app.panel.timestep.value = 10
    assert app.estimate_lines.points.shape[0] == num_links
    app.panel.learn.trail_of.value = "all samples"
    assert app.estimate_lines.points.shape[0] == num_samples * num_links
    assert app.trail.points.shape[0] == (app.state + 1) * num_samples * num_links
    assert (app.joints.batched_scales == 1).all()  # every sample's joints again


def test_samples_and_highlight_change_what_is_drawn(app):
    app.panel.samples.value = 5
    settle(app)
    assert app.solved.view.num_samples == 5 and app.links.points.shape == (5 * 3, 2, 3)
    assert app.panel.highlight.options == ("best", "1", "2", "3", "4", "5")  # counted as people count
    app.panel.highlight.value = "3"
    colors = app.links.colors.reshape(5, 3 * 2, 3)
    assert (colors[2] != colors[0]).any() and (colors[0] == colors[1]).all()
    assert "sample 3 of 5" in app.panel.readout_text.content


def test_ddim_with_fewer_steps_gives_fewer_states(app):
    app.panel.steps.value = 5
    app.panel.sampler.value = "ddim"
    settle(app)
    view = app.solved.view
    assert view.num_states == 6 and view.labels[0] == app.panel.timestep.max and view.labels[-1] == 0
    assert not app.panel.steps.disabled and "ddim, 5 steps" in app.panel.readout_text.content
    app.panel.timestep.value = view.labels[2] + 1  # between two visited states: the nearest one is shown
    assert app.state == 2


def test_refine_draws_the_polished_pose_beside_the_raw_one(app, solver):
    app.panel.refine.value = True
    settle(app)
    view = app.solved.view
    assert view.refined and app.refined_lines.visible and app.refined_tips.visible
    assert "the best by refined tip error" in app.panel.readout_text.content  # says what "best" ranks by
    assert np.allclose(app.refined_tips.batched_positions[:, :2], view.final_joints[:, -1], atol=1e-5)
    assert np.median(view.final_tip_error) < np.median(view.tip_error[-1])  # the polish helps
    # drawn over the other arms, but under the highlighted arm and the target's cross (a top-down camera)
    highlighted = app.joints.batched_positions.reshape(view.num_samples, -1, 3)[app.highlight_index(), :, 2]
    refined_height = app.refined_tips.batched_positions[:, 2]
    cross_height = app.gizmo.position[2] + app.cross.position[2]
    assert (refined_height > 0).all() and (refined_height < highlighted.min()).all()
    assert (app.refined_lines.points[..., 2] < highlighted.min()).all() and cross_height > highlighted.max()
    app.panel.timestep.value = 5
    assert not app.refined_lines.visible  # only beside the final pose


def test_the_estimate_toggle_ghosts_the_denoisers_x0_of_the_step_shown(app, solver):
    view = app.solved.view
    assert view.estimate_joints.shape == (view.num_states - 1, 16, solver.num_links + 1, 2)
    assert not app.estimate_lines.visible  # off by default
    app.panel.learn.trail_of.value = "all samples"  # every sample's x̂0
    app.panel.show_estimate.value = True
    app.panel.timestep.value = 10
    state = app.state
    drawn = app.estimate_lines.points.reshape(16, solver.num_links, 2, 3)[..., :2]
    assert app.estimate_lines.visible and np.allclose(drawn[:, :, 0], view.estimate_joints[state - 1][:, :-1])
    # the same solve through the public API: x̂0 of that step, as joint values
    generator = torch.Generator().manual_seed(int(app.panel.seed.value))
    out = solver.solve(
        app.target[None], num_samples=16, generator=generator, return_trajectory=True, return_estimates=True
    )
    expected = ikdp.forward_kinematics(out.estimates[state - 1, 0].double(), torch.tensor(solver.lengths).double())
    assert np.allclose(drawn[:, :, 1], expected.numpy()[:, 1:], atol=1e-4)
    app.panel.timestep.value = app.panel.timestep.max  # t = T: no estimate yet
    assert not app.estimate_lines.visible
    app.panel.show_estimate.value = False


def test_drawing_from_the_prior_shows_k_prior_poses_until_the_next_solve(app, solver):
    joints = app.draw_prior()
    assert joints.shape == (16, solver.num_links + 1, 2) and np.allclose(joints[:, 0], 0.0)
    bones = np.linalg.norm(np.diff(joints, axis=1), axis=-1)
    assert np.allclose(bones, solver.lengths)  # real poses of this arm
    assert np.allclose(app.writer.view.prior_lines.points[..., :2].reshape(16, -1, 2, 2)[:, :, 0], joints[:, :-1])
    assert "poses drawn from the prior" in app.panel.learn.legend.content  # the legend lists them while drawn
    app.move_target((0.2, 1.3))
    settle(app)
    assert app.writer.view.prior_lines is None
    assert "prior" not in app.panel.learn.legend.content


def test_export_writes_the_denoising_as_a_gif_and_the_trail_as_a_png(app, tmp_path):
    import imageio.v2 as imageio
    from viz_helpers import read_png

    app.panel.duration.value = 2.0
    gif, png = app.export(tmp_path)
    view = app.solved.view
    frames = imageio.mimread(gif)
    assert gif.suffix == ".gif" and 2 < len(frames) <= 41 and frames[0].shape[:2] == (480, 480)
    assert not np.array_equal(frames[0], frames[-1])  # the arms move from noise to the final pose
    image = read_png(png.read_bytes())
    assert image.shape == (840, 800, 3) and (image.min(axis=-1) < 100).any()  # dark final poses drawn
    image = image[40:]  # under the title's band: the picture, 800 square
    red = (image[..., 0] > 180) & (image[..., 1] < 80) & (image[..., 2] < 80)
    red[520:, :420] = False  # the legend's box (bottom left) has a red cross of its own
    rows, cols = np.nonzero(red)
    reach = float(np.sum(view.lengths))
    centre = (np.array([cols.mean(), rows.mean()]) - 400) / 400 * 1.05 * reach * np.array([1, -1])
    assert np.allclose(centre, view.target, atol=0.1 * reach)  # the cross where the target is
    assert f"seed{app.solved.request.seed}" in gif.name and png.name.endswith("_trail.png")


def test_every_legend_entry_names_something_drawn_and_the_export_lists_what_it_draws(app, tmp_path, monkeypatch):
    """The legend showed a ramp of tips where one tip is drawn, had no entry for the compared sampler's arms, and the
    exported PNG's legend left out the grey final arms under a title that ran over the reach circle."""
    from viz_helpers import read_png

    from ikdp_viz import downloads

    legend = app.writer.frame.legend
    tips = [entry for entry in legend if "tip" in entry.text]
    assert len(tips) == 1 and tips[0].swatch.shape == "dot"  # one dot drawn, in its shade at the step shown
    assert tips[0].swatch.faint is not None
    assert int(app.tips.batched_scales.sum()) == 1  # ... as the scene draws: the highlighted sample's tip alone
    assert not any("same x_T" in entry.text for entry in legend)
    app.panel.learn.compare.value = "ddim"
    settle(app)
    assert any("ddim from the same x_T" in entry.text for entry in app.writer.frame.legend)
    assert "ddim from the same x_T" in app.panel.learn.legend.content
    app.panel.learn.compare.value = "off"
    settle(app)
    pictures = []
    monkeypatch.setattr(downloads, "write_gif", lambda picture, path, **_: pictures.append(picture) or path)
    _, png = app.downloads.export(tmp_path)
    texts = [entry.text for entry in pictures[0].legend]
    drawn = [entry.text for entry in app.writer.frame.legend if entry.flat]
    assert texts == [*drawn, "target"] and any("other samples" in text for text in texts)  # the grey final arms
    assert not any("tip" in text for text in texts)  # the PNG draws no tips
    image = read_png(png.read_bytes()).astype(int)[:100]  # the top: the title and the top of the reach circle
    text = image.max(axis=-1) < 100
    near_text = np.zeros_like(text)  # a letter's grey edges are not the circle
    for shift in range(-3, 4):
        near_text |= np.roll(text, shift, axis=0) | np.roll(text, shift, axis=1)
    circle = (np.ptp(image, axis=-1) <= 8) & (np.abs(image[..., 0] - 150) <= 25) & ~near_text
    title_rows = np.flatnonzero(text.any(axis=1))
    circle_rows = np.flatnonzero(circle[:, 380:420].any(axis=1))  # the circle's top, over the base
    assert len(title_rows) and len(circle_rows)
    assert circle_rows.min() > title_rows.max(), (title_rows, circle_rows)  # the title above the circle, clear of it


def test_the_gif_keeps_the_viewers_clock_and_colours(app, tmp_path):
    """The GIF gave every step the same time (half of it pure noise) and drew the other
    samples black at t = 0; it follows the viewer's noise-level clock and its light grey now."""
    from PIL import Image

    from ikdp_viz.downloads import export_picture, gif_states
    from ikdp_viz.style import OTHERS_FINAL

    app.panel.duration.value = 4.0
    gif, _ = app.export(tmp_path)
    with Image.open(gif) as image:
        durations = [image.seek(index) or image.info["duration"] for index in range(image.n_frames)]
    picture = export_picture(app.solved, app.writer.settings(), app.solver)
    states, seconds = gif_states(picture.offsets, 4.0, 41)
    assert np.allclose(durations, 1000 * seconds, atol=20)  # GIF durations are whole 10 ms
    noisy = states < picture.num_states // 2  # the first half of the states, t = T .. T/2: mostly noise
    assert seconds[noisy].sum() < 0.25 * seconds.sum()  # quickly past, as in the viewer (equal steps: half)
    others = np.arange(app.solved.view.num_samples) != picture.highlight
    assert (picture.arms[-1][others] == OTHERS_FINAL).all()  # the viewer's light grey, not black


def test_the_cross_lies_on_the_cameras_ray_through_the_target_above_every_arm(app):
    for point in [(0.3, 1.1), (10.0, -10.0)]:  # inside, and clamped to the boundary
        app.move_target(point)
        settle(app)
        ground = np.array([*app.target, 0.0])
        camera = np.asarray(app.server.initial_camera.position)
        cross = np.asarray(app.cross.position)
        assert np.linalg.norm(np.cross(cross - ground, camera - ground)) < 1e-9  # the same pixel as the target
        sizes = app.writer.view.sizes
        assert cross[2] - 0.05 * sizes.cross > HIGHLIGHT_LIFT * sizes.joint + sizes.tip  # over the highlighted tip


def test_each_gif_frame_says_its_t_and_progress_is_reported_per_frame(app, tmp_path):
    import imageio.v2 as imageio

    calls: list[tuple[int, int]] = []
    gif, _ = app.export(tmp_path, progress=lambda done, total: calls.append((done, total)))
    frames = imageio.mimread(gif)
    assert calls == [(done, len(frames)) for done in range(1, len(frames) + 1)]
    corner = [np.asarray(frame)[:40, :100, :3] for frame in frames]  # top left, outside the workspace's circle
    assert all((box.max(axis=-1) < 100).sum() > 20 for box in corner)  # dark text on every frame
    assert not np.array_equal(corner[0], corner[-1])  # t = T first, t = 0 last: different labels
    from ikdp_viz.downloads import time_label

    view = app.solved.view
    assert time_label(view, 0) == f"t = {app.solver.timesteps}" and time_label(view, view.num_states - 1) == "t = 0"


def test_a_fixed_seed_repeats_the_solve_and_new_seed_each_move_changes_it(app):
    drag_gizmo(app, 0.5, 1.5)
    settle(app)
    first = app.solved.view.joints.copy()
    drag_gizmo(app, 0.6, 1.5)
    drag_gizmo(app, 0.5, 1.5)
    settle(app)
    assert np.array_equal(app.solved.view.joints, first)
    app.panel.new_seed.value = True
    drag_gizmo(app, 0.6, 1.5)
    settle(app)
    seed = app.solved.request.seed
    assert seed == app.panel.seed.value and f"seed {seed}" in app.panel.readout_text.content


def test_the_newest_target_wins_and_the_server_keeps_answering_during_a_solve(app, solver, monkeypatch):
    entered, release = threading.Event(), threading.Event()
    real_solve = solver.solve

    asked = []  # the targets each solve that ran was given

    def slow_solve(targets, **options):
        asked.append(np.asarray(targets, dtype=np.float64).reshape(-1)[:2].round(3).tolist())
        if not entered.is_set():
            entered.set()
            assert release.wait(30)
        return real_solve(targets, **options)

    monkeypatch.setattr(solver, "solve", slow_solve)
    monkeypatch.setattr(app.worker, "stale_grace", None)  # the screen is never deemed starved here
    monkeypatch.setattr(app.worker, "cancel_fraction", float("inf"))  # the blocked solve counts as early
    stats = app.worker.stats
    before = (stats.replaced, stats.cancelled, stats.delivered)
    drag_gizmo(app, 1.0, 1.0)
    assert entered.wait(30)  # this solve now blocks the worker
    drag_gizmo(app, 0.0, 1.5)  # waits, then is replaced
    drag_gizmo(app, -1.2, 0.4)  # the newest
    app.panel.timestep.value = 3  # the panel still answers, on the previous solve
    assert "x = -1.200, y = +0.400" in app.panel.target_text.content and app.state == app.solved.view.num_states - 4
    release.set()
    settle(app)
    assert np.allclose(app.solved.view.target, [-1.2, 0.4])
    # (0, 1.5) never ran (replaced in the worker's queue, or by the newer target before the loop submitted it);
    # (1, 1) stopped at its first denoising step once released; only the newest was drawn
    assert [0.0, 1.5] not in asked and asked[0] == [1.0, 1.0] and asked[-1] == [-1.2, 0.4], asked
    assert (stats.cancelled - before[1], stats.delivered - before[2]) == (1, 1)


class CancelAfter(threading.Event):
    """An event that reads as set from its `calls`-th check on: a newer request arriving mid-solve."""

    def __init__(self, calls: int):
        super().__init__()
        self.checks, self.calls = 0, calls

    def is_set(self) -> bool:
        self.checks += 1
        return self.checks >= self.calls


def test_a_cancelled_solve_stops_after_the_step_under_way_through_the_cores_callback(solver):
    request = SolveRequest(solver, np.array([1.0, 1.0]), 4, "ddpm", None, 0, 0, 0.0, True)
    cancel = CancelAfter(5)  # checked once before the solve, then once after each reverse step
    with pytest.raises(Cancelled):
        solve(request, cancel)
    assert cancel.checks == 5 < solver.timesteps  # stopped after step 4 of T: the callback returned True there
    done = threading.Event()
    done.set()
    with pytest.raises(Cancelled):
        solve(request, done)  # already stale: never starts
    solved = solve(request, threading.Event())  # never set: the solve runs to the end
    assert solved.view.num_states == solver.timesteps + 1


def test_a_drag_shows_each_final_pose_at_once_and_the_release_plays_the_denoising(app):
    shown = []
    app.panel.timestep.on_update(lambda event: shown.append(app.panel.timestep.value))
    app.panel.duration.value = 0.3
    drag_gizmo(app, -0.4, 1.2)  # mid-drag: the arm follows at its final pose
    settle(app)
    assert np.allclose(app.solved.view.target, [-0.4, 1.2]) and app.state == app.solved.view.num_states - 1
    assert set(shown) <= {0}  # never an intermediate step
    drag_gizmo(app, -0.4, 1.2, phase="end")  # released where the last update left it: no new solve, a replay
    settle(app)
    assert shown[0] == app.solved.view.labels[0] and shown[-1] == 0 and len(shown) >= 2
    assert all(later <= earlier for earlier, later in zip(shown, shown[1:], strict=False))
    assert app.panel.play_button.label == "Play"
    shown.clear()
    app.move_target((0.3, -1.0))  # a move in one go (not a drag) animates too
    settle(app)
    assert shown[0] == app.solved.view.labels[0] and shown[-1] == 0
    app.toggle_play()  # at the end: plays again from t = T
    settle(app)
    assert app.state == app.solved.view.num_states - 1


def test_switching_checkpoints_redraws_the_arm_with_its_links(app, tiny_checkpoint, two_link_checkpoint, tmp_path):
    junk = tmp_path / "junk.pt"
    junk.write_text("not a checkpoint")
    app.checkpoints = {"tiny.pt": Path(tiny_checkpoint), "two.pt": Path(two_link_checkpoint), "junk.pt": junk}
    app.panel.checkpoint.options = tuple(app.checkpoints)
    app.panel.checkpoint.value = "two.pt"
    settle(app)
    assert app.solver.num_links == 2 and app.solved.view.num_links == 2
    assert app.links.points.shape == (16 * 2, 2, 3) and app.joints.batched_positions.shape == (16 * 3, 3)
    assert app.panel.timestep.max == 12 and app.solved.view.num_states == 13
    assert "**A 2-link planar arm** (N = 2)" in app.panel.model_text.content
    app.panel.checkpoint.value = "junk.pt"  # refused: the model stays, the panel says why
    assert app.solver.num_links == 2 and app.panel.checkpoint.value == "two.pt"
    assert "Could not load" in app.panel.model_text.content and "junk.pt" in app.panel.model_text.content


def test_steps_shows_t_while_ddpm_takes_all_and_the_choice_comes_back(app, solver):
    steps = app.panel.steps
    assert app.panel.sampler.value == "ddpm" and steps.disabled and steps.value == solver.timesteps
    app.panel.sampler.value = "ddim"
    settle(app)
    assert not steps.disabled and steps.value == 20 and app.solved.request.steps == 20
    steps.value = 7
    settle(app)
    assert app.solved.request.steps == 7 and app.solved.view.num_states == 8
    app.panel.sampler.value = "ddpm"
    settle(app)
    assert steps.disabled and steps.value == solver.timesteps and app.solved.view.num_states == solver.timesteps + 1
    app.panel.sampler.value = "dpmpp2m"
    settle(app)
    assert not steps.disabled and steps.value == 7 and app.solved.request.steps == 7


def test_a_new_model_clamps_the_old_target_and_says_so(app, two_link_checkpoint):
    app.move_target((0.0, 2.8))  # inside the three-link arm's reach of 3, outside the two-link arm's 2
    settle(app)
    assert "Clamped" not in app.panel.target_text.content
    assert app.load_checkpoint(Path(two_link_checkpoint))
    settle(app)
    np.testing.assert_allclose(app.target, [0.0, 2.0], atol=1e-12)
    assert "Clamped to the workspace boundary* (r = 2.00)" in app.panel.target_text.content
    assert app.panel.steps.disabled and app.panel.steps.value == 12  # DDPM on the new model: all its T = 12 steps


def test_the_dropdown_offers_only_models_of_the_arm_this_viewer_draws(
    solver, tiny_checkpoint, two_link_checkpoint, tiny_chain_checkpoint, tmp_path
):
    import shutil

    from ikdp_viz.app import checkpoint_arm_kind

    folder = tmp_path / "models"
    folder.mkdir()
    for name, source in (("planar3.pt", tiny_checkpoint), ("planar2.pt", two_link_checkpoint)):
        shutil.copy(source, folder / name)
    shutil.copy(tiny_chain_checkpoint, folder / "robot.pt")
    (folder / "junk.pt").write_text("not a checkpoint")
    assert [checkpoint_arm_kind(folder / name) for name in ("planar3.pt", "robot.pt", "junk.pt")] == [
        "planar", "chain", None
    ]  # fmt: skip
    with running_app(solver, solve_now=False, checkpoints=list_checkpoints(folder), checkpoint_folder=folder) as app:
        assert set(app.panel.checkpoint.options) == {"planar2.pt", "planar3.pt", str(tiny_checkpoint)}
        shutil.copy(tiny_chain_checkpoint, folder / "robot2.pt")  # trained while the viewer runs
        shutil.copy(two_link_checkpoint, folder / "planar4.pt")
        app.refresh_checkpoints()
        assert set(app.panel.checkpoint.options) == {"planar2.pt", "planar3.pt", "planar4.pt", str(tiny_checkpoint)}
    chain_solver = ikdp.load(tiny_chain_checkpoint)
    with running_app(
        chain_solver, solve_now=False, checkpoints=list_checkpoints(folder), checkpoint_folder=folder
    ) as app:
        assert set(app.panel.checkpoint.options) == {"robot.pt", "robot2.pt", str(tiny_chain_checkpoint)}


def test_one_joint_on_both_axes_moves_the_other_dropdown_on(app):
    controls = app.panel.joint_space
    controls.show.value = True  # drawn before the next line: the writer offers the arm's three joints
    assert controls.first.options == ("θ1", "θ2", "θ3") and controls.joints() == (0, 1)
    controls.second.value = "θ3"
    controls.first.value = "θ3"  # the same joint as the y axis: the y axis moves on, in the panel
    assert (controls.first.value, controls.second.value) == ("θ3", "θ1") and controls.joints() == (2, 0)
    controls.second.value = "θ3"
    assert (controls.first.value, controls.second.value) == ("θ1", "θ3") and controls.joints() == (0, 2)
    app.writer.flush()
    labels = [label.text for label in app.writer.stage.joint_space.labels[:2]]
    assert labels == ["θ1", "θ3"]  # the square's axes say what the dropdowns say
    controls.show.value = False


def test_list_checkpoints_finds_every_pt_file_and_the_one_given(tmp_path):
    (tmp_path / "b.pt").write_bytes(b"")
    (tmp_path / "a.pt").write_bytes(b"")
    (tmp_path / "notes.txt").write_text("")
    elsewhere = tmp_path.parent / "other.pt"
    assert list(list_checkpoints(tmp_path)) == ["a.pt", "b.pt"]
    assert list(list_checkpoints(tmp_path, elsewhere)) == ["a.pt", "b.pt", str(elsewhere)]
    assert list(list_checkpoints(tmp_path, tmp_path / "a.pt")) == ["a.pt", "b.pt"]


@pytest.mark.slow
def test_a_fuzz_of_moves_sampler_changes_and_reloads_from_several_threads_ends_on_the_newest_target(
    app, tiny_checkpoint, two_link_checkpoint, capfd
):
    """The threading design: no exception anywhere, solves drawn in request order, the newest drawn last."""
    from ikdp.samplers import sampler_names

    app.panel.duration.value = 0.2  # animations run (and get interrupted) throughout
    failures: list[BaseException] = []

    def run(action, count: int, seed: int) -> None:
        generator = np.random.default_rng(seed)
        try:
            for _ in range(count):
                action(generator)
        except BaseException as error:  # noqa: BLE001 - any failure fails the test below
            failures.append(error)

    def move(generator) -> None:
        if generator.random() < 0.5:
            drag_gizmo(app, *generator.uniform(-4, 4, size=2), phase=str(generator.choice(["update", "end"])))
        else:
            app.move_target(generator.uniform(-4, 4, size=2))

    def change_sampler(generator) -> None:
        app.panel.sampler.value = str(generator.choice(sampler_names()))
        app.panel.steps.value = int(generator.integers(2, 10))

    def reload(generator) -> None:
        app.load_checkpoint(Path(two_link_checkpoint if generator.random() < 0.5 else tiny_checkpoint))

    def scrub(generator) -> None:
        app.panel.timestep.value = int(generator.integers(0, app.panel.timestep.max + 1))
        app.panel.highlight.value = "best"

    threads = [threading.Thread(target=run, args=(move, 40, seed)) for seed in range(3)]
    threads += [threading.Thread(target=run, args=(change_sampler, 15, 10))]
    threads += [threading.Thread(target=run, args=(reload, 4, 11))]
    threads += [threading.Thread(target=run, args=(scrub, 20, 12))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(120)
    assert not failures, failures
    app.move_target((0.4, -1.1))  # the newest target of all
    settle(app)
    assert np.allclose(app.solved.view.target, [0.4, -1.1]) and np.allclose(app.target, [0.4, -1.1])
    assert app.solved.request.solver is app.solver and np.allclose(app.gizmo.position[:2], [0.4, -1.1])
    assert app.solved.view.num_links == app.solver.num_links == app.links.points.shape[0] // 16
    arrivals = [arrival for arrival, _, _ in app.latencies]
    assert arrivals == sorted(arrivals)  # never an older solve drawn after a newer one
    assert app.latencies[-1][2]  # the last drawn was the newest when it finished
    assert app.worker.stats.failed == 0
    assert "Traceback" not in capfd.readouterr().err


def test_the_animation_clock_is_spaced_by_noise_level_and_says_so(app):
    from ikdp_viz.frame import noise_levels, state_offsets

    app.panel.duration.value = 4.0
    note = app.panel.learn.clock_note.content
    assert app.panel.learn.clock.value == "noise level" and "by noise level σ" in note and "of 4.0 s" in note
    app.toggle_play()  # play from t = T
    animation = app.writer.animation
    sigmas = noise_levels(app.solved.view.labels, app.solver.model.schedule.sqrt_one_minus_alphas_cumprod.numpy())
    assert animation is not None and np.allclose(animation.offsets, state_offsets(sigmas, "noise level", 4.0))
    app.toggle_play()  # pause
    app.panel.learn.clock.value = "step"
    assert "evenly by step" in app.panel.learn.clock_note.content
    app.panel.duration.value = 0.0


def test_the_legend_names_every_colour_drawn_and_follows_the_trail_setting(app):
    from ikdp_viz.style import ACCENT_DARK, ESTIMATE, PRIOR, REFINED, TARGET_RED, TIP_DARK, css

    legend = app.panel.learn.legend.content
    for words in ("x̂0", "refined", "prior"):  # show x̂0 off, refine off, no prior's draw: none of them is drawn
        assert words not in legend
    app.panel.show_estimate.value = True
    app.panel.refine.value = True
    settle(app)
    app.draw_prior()
    app.panel.timestep.value = app.panel.timestep.max // 2  # x̂0 is drawn between t = T and t = 0
    legend = app.panel.learn.legend.content
    for color in (ACCENT_DARK, TIP_DARK, ESTIMATE, REFINED, PRIOR, TARGET_RED):
        assert css(color) in legend  # each colour of the scene has its swatch
    for words in ("trail of the highlighted sample", "x̂0", "refined", "prior", "tip", "target"):
        assert words in legend
    app.panel.learn.trail_of.value = "all samples"
    assert "trails of all samples" in app.panel.learn.legend.content
    app.panel.show_estimate.value = app.panel.refine.value = False
    settle(app)
    assert not any(words in app.panel.learn.legend.content for words in ("x̂0", "refined", "prior"))


def test_the_page_opens_on_pure_noise_and_plays_when_a_tab_connects(solver):
    """The command line's viewer played the first denoising before anyone connected, so a
    tab opened on the finished pose; and viser's software-WebGL toast covered the scene."""
    from types import SimpleNamespace

    sent = []
    tab = SimpleNamespace(_websock_connection=SimpleNamespace(queue_message=sent.append))
    with running_app(solver, animation_seconds=1.0, wait_for_tab=True) as app:
        assert app.wait_until_still(60)
        assert app.solved is not None and app.state == 0 and not app.playing  # pure noise, waiting
        app.writer.ask(tabs=[tab])
        app.writer.flush()
        assert app.playing and app.state == 0  # plays from t = T, holding pure noise a moment first
        assert [message.uuid for message in sent] == ["webgl-software-rendering"]
        settle(app)
        assert app.state == app.solved.view.num_states - 1
        app.writer.ask(tabs=[tab])  # a second tab: the solve was seen, nothing replays
        app.writer.flush()
        assert not app.playing


def test_a_new_tab_plays_the_denoising_once_its_page_has_drawn_a_frame(solver):
    """viser calls a connection on the page's first camera message, before the page has drawn: played from there, a
    CPU's page showed its first frame most of the way through the denoising."""
    import time
    from types import SimpleNamespace

    drawn, asked = threading.Event(), threading.Event()

    def get_render(height, width, **options):  # the page answers once it has drawn the scene
        asked.set()
        assert drawn.wait(30)
        return np.zeros((height, width, 3), np.uint8)

    tab = SimpleNamespace(_websock_connection=SimpleNamespace(queue_message=lambda message: None),
                          get_render=get_render, camera=SimpleNamespace(on_update=lambda callback: None))  # fmt: skip
    with running_app(solver, animation_seconds=1.0, wait_for_tab=True) as app:
        assert app.wait_until_still(60) and app.state == 0 and not app.playing  # pure noise, waiting
        connecting = threading.Thread(target=app._on_connect, args=(tab,))
        connecting.start()
        try:
            assert asked.wait(30)
            time.sleep(0.3)
            app.writer.flush()
            assert not app.playing and app.state == 0  # the page has not drawn yet: nothing plays unseen
        finally:
            drawn.set()
            connecting.join(30)
        app.writer.flush()
        assert app.playing and app.state == 0  # from t = T, now that the page draws
