"""The 3-D viewer in-process: a chain (Panda) checkpoint on a real viser server, driven through its handles.

A tiny Panda model (T = 10) trained for a few steps: the poses are poor, the drawing
and the readouts are what is checked. K = 4; the animation duration is 0, so every
check reads a finished frame.
"""

from __future__ import annotations

import asyncio
import re
import time

import numpy as np
import pytest
from viz_helpers import running_app, settle, solves_shown_by_a_robot_drag

import ikdp
from ikdp_viz.chain_scene import gizmo_pose, mesh_poses, skeleton_segments
from ikdp_viz.robot_view import RobotView

K = 4


@pytest.fixture
def app(tiny_chain_checkpoint):
    with running_app(ikdp.load(tiny_chain_checkpoint), solve_now=False, animation_seconds=0.0) as app:
        app.panel.samples.value = K  # asks for a solve of the first target
        settle(app)
        yield app


def drag_pose(app, position, wxyz, phase: str = "end") -> None:
    """Do what viser does when the page drags the 6-DoF gizmo: set its pose, then fire its callback."""
    import viser

    gizmo = app.writer.view.gizmo
    gizmo._impl.position, gizmo._impl.wxyz = np.asarray(position, float), np.asarray(wxyz, float)
    event = viser.TransformControlsEvent(client=None, client_id=None, target=gizmo, phase=phase)
    asyncio.run_coroutine_threadsafe(app.on_gizmo_update(event), app.server.get_event_loop()).result(timeout=10)


def test_a_solve_draws_every_sample_as_a_robot_and_a_skeleton(app):
    writer, view = app.writer, app.solved.view
    arm = app.solver.arm
    assert isinstance(writer.view, RobotView)
    assert view.num_samples == K and app.state == view.num_states - 1
    assert len(writer.view.ghosts) == len(writer.view.robot_meshes) == 9  # the Panda's collision meshes, one node each
    positions, wxyzs = mesh_poses(arm, view.final_joint_values, writer.view.mesh_links, writer.view.mesh_offsets)
    for index, node in enumerate(writer.view.ghosts):
        np.testing.assert_allclose(node.batched_positions, positions[:, index], atol=1e-5)
        np.testing.assert_allclose(node.batched_wxyzs, wxyzs[:, index], atol=1e-5)
    highlight = app.highlight_index()
    assert highlight == view.best_sample()
    scales = writer.view.ghosts[0].batched_scales
    assert scales[highlight] == 0 and (np.delete(scales, highlight) == 1).all()  # drawn opaque on its own
    for index, node in enumerate(writer.view.robot):
        np.testing.assert_allclose(node.position, positions[highlight, index], atol=1e-5)
    assert writer.view.skeletons.points.shape == (K * arm.num_joints, 2, 3)  # one node holds all K skeletons
    np.testing.assert_allclose(writer.view.skeletons.points[arm.num_joints - 1, 1], view.points[-1, 0, -1], atol=1e-6)
    hand_position, _ = gizmo_pose(arm, view.final_joint_values[highlight])
    np.testing.assert_allclose(writer.view.hand.position, hand_position, atol=1e-6)
    np.testing.assert_allclose(writer.view.gizmo.position, app.target[:3], atol=1e-6)
    assert "Target" in app.panel.target_text.content and "mm" in app.panel.target_text.content


def test_the_timestep_slider_puts_that_state_on_screen(app):
    app.panel.learn.trail_of.value = "all samples"  # every hand's path
    writer, view = app.writer, app.solved.view
    app.show_state(0)
    assert app.state == 0 and app.panel.timestep.value == app.solver.timesteps
    np.testing.assert_allclose(writer.view.skeletons.points, skeleton_segments(view.points[0]), atol=1e-6)
    assert not writer.view.trail.visible  # nothing before pure noise
    positions, _ = mesh_poses(app.solver.arm, view.joint_values[0], writer.view.mesh_links, writer.view.mesh_offsets)
    np.testing.assert_allclose(writer.view.ghosts[3].batched_positions, positions[:, 3], atol=1e-5)
    colors_at_noise = writer.view.ghosts[0].batched_colors.copy()
    assert not app.panel.show_trail.value  # off at start in 3-D
    app.panel.show_trail.value = True
    app.panel.timestep.value = 4  # as the page's slider does: the nearest state
    assert int(view.labels[app.state]) == 4 and app.state == app.solver.timesteps - 4
    np.testing.assert_allclose(writer.view.skeletons.points, skeleton_segments(view.points[app.state]), atol=1e-6)
    assert writer.view.trail.visible and len(writer.view.trail.points) == (app.state + 1) * K  # the hands' paths so far
    assert (writer.view.ghosts[0].batched_colors.astype(int) <= colors_at_noise).all()  # darker toward t = 0


def test_the_gizmo_sets_the_pose_target(app):
    position = app.target[:3] + np.array([0.05, -0.02, -0.03])
    wxyz = np.array([0.0, 1.0, 0.0, 0.0])  # the hand pointing down
    drag_pose(app, position, wxyz)
    settle(app)
    np.testing.assert_allclose(app.target, np.concatenate((position, wxyz)), atol=1e-9)
    np.testing.assert_allclose(app.solved.request.target, app.target)
    np.testing.assert_allclose(app.solved.view.target, app.target)


def test_refine_shows_the_polished_error_in_millimetres_and_degrees(app):
    app.panel.refine.value = True
    settle(app)
    view = app.solved.view
    assert view.refined and app.writer.view.refined_lines.visible
    text = app.panel.readout_text.content
    assert re.search(r"refined \(5 DLS steps\): \d+\.\d mm / \d+\.\d\d°", text), text
    best = re.search(
        r"\*\*Hand error\*\*, sample (\d+) of 4 \(the best by refined hand error\): [\d.]+ mm / [\d.]+°", text
    )
    assert best, text
    view = app.solved.view
    raw_best = int(np.argmin(view.position_error[-1] + 0.1 * view.rotation_error[-1])) + 1
    named = f"by raw hand error at t = 0 the best is sample {raw_best}"
    assert (named in text) == (raw_best != int(best.group(1)))  # the raw ranking named when it differs
    app.show_state(0)
    assert not app.writer.view.refined_lines.visible  # the polish belongs to the final pose


def test_the_chart_plots_the_hand_error_in_millimetres_and_says_so(app):
    view, highlight = app.solved.view, app.highlight_index()
    t, median, chosen, _ = app.panel.plot.data
    order = np.argsort(view.labels, kind="stable")
    np.testing.assert_allclose(chosen, np.log10(np.maximum(1000 * view.position_error[order, highlight], 1e-6)))
    low, high = app.panel.plot.scales["y"]["range"]
    assert 10**low <= 1000 * view.position_error.min() + 1e-9 and 1000 * view.position_error.max() <= 10**high
    x_axis, y_axis = app.panel.plot.axes
    assert y_axis["label"] == "mm, log scale" and "t" in x_axis["label"]
    assert [float(value) for value in y_axis["values"]] == [10.0**exponent for exponent in y_axis["splits"]]
    assert app.panel.plot.title == "hand position error against t"


def test_the_prior_and_a_planar_checkpoint_are_handled(app, tiny_checkpoint):
    joints = app.draw_prior()
    assert joints.shape == (K, app.solver.arm.num_joints + 1, 3) and app.writer.view.prior_lines is not None
    assert not app.load_checkpoint(tiny_checkpoint)  # a planar model: this viewer draws a robot
    assert "Could not load" in app.panel.model_text.content and "planar" in app.panel.model_text.content
    assert app.solver.arm.kind == "chain"


def test_a_solve_is_reproducible_from_its_seed(app):
    first = app.solved.view.final_joint_values.copy()
    app.request_solve()
    settle(app)
    np.testing.assert_array_equal(app.solved.view.final_joint_values, first)


def test_the_floor_grid_is_spaced_in_round_numbers_near_a_tenth_of_the_reach():
    from ikdp_viz.robot_view import grid_cell

    assert [grid_cell(reach) for reach in (0.986, 1.0, 3.0, 0.3, 12.0)] == [0.1, 0.1, 0.5, 0.05, 2.0]


def test_the_joint_space_controls_are_hidden_for_a_robot_and_shown_for_a_planar_arm(app, tiny_checkpoint):
    assert app.panel.joint_space.folder.visible is False  # the view draws planar arms only
    with running_app(ikdp.load(tiny_checkpoint), solve_now=False, animation_seconds=0.0) as planar:
        assert planar.panel.joint_space.folder.visible is True


def test_a_pause_draws_the_state_in_full_again(app):
    """While the animation plays the trail is light (every s-th state); paused, the frame is a still one."""
    writer, last = app.writer, app.solved.view.num_states - 1
    app.panel.learn.trail_of.value = "all samples"  # the light trail while playing is every sample's
    app.panel.show_trail.value = True
    app.panel.duration.value = 1.0 * last  # a state a second: caught on the way below
    app.show_state(0)
    app.toggle_play()
    deadline = time.monotonic() + 20
    while app.state < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert app.playing and 0 < app.state < last
    assert not any(node.visible for node in writer.view.ghosts)  # while it plays the skeletons stand in for the ghosts
    assert writer.view.skeletons.visible and all(node.visible for node in writer.view.robot)
    app.toggle_play()  # pause
    assert not app.playing and writer.view.skeletons.visible and all(node.visible for node in writer.view.ghosts)
    positions, _ = mesh_poses(app.solver.arm, app.solved.view.pose_at(app.state, 0), writer.view.mesh_links,
                              writer.view.mesh_offsets)  # fmt: skip
    np.testing.assert_allclose(
        writer.view.ghosts[2].batched_positions[0], positions[2], atol=1e-5
    )  # at the paused state
    assert len(writer.view.trail.points) == (app.state + 1) * K  # the whole trail up to the state


def test_the_3d_legend_names_the_robots_skeletons_and_hand_frame(app):
    legend = app.panel.learn.legend.content
    assert "highlighted robot" in legend and "skeletons" in legend and "hand frame" in legend
    assert not any(words in legend for words in ("x̂0", "refined", "prior"))  # none of them drawn yet
    app.panel.show_estimate.value = True
    app.panel.refine.value = True
    settle(app)
    app.draw_prior()
    assert app.solved.view.refined
    app.panel.timestep.value = app.panel.timestep.max // 2  # x̂0 is drawn between t = T and t = 0
    settle(app)
    legend = app.panel.learn.legend.content
    assert "x̂0" in legend and "refined" in legend and "poses drawn from the prior" in legend
    app.panel.refine.value = False  # the next solve: not refined, and the prior's draw goes
    settle(app)
    assert "refined" not in app.panel.learn.legend.content and "prior" not in app.panel.learn.legend.content


def test_the_followed_robot_stands_out_and_the_others_recede(app):
    from ikdp_viz.style import HIGHLIGHTED_ROBOT

    writer, view = app.writer, app.solved.view
    highlight, num_joints = app.highlight_index(), view.num_joints
    for state in (1, view.num_states - 1):  # early and late: the followed robot is the same strong blue
        app.show_state(state)
        assert all(node.color == HIGHLIGHTED_ROBOT for node in writer.view.robot)
    skeleton = writer.view.skeletons.colors.reshape(view.num_samples, num_joints, 2, 3)[:, 0, 0].astype(int)
    others = np.delete(skeleton, highlight, axis=0)
    assert (others.min(axis=1) >= 150).all() and skeleton[highlight].sum() < others.sum(axis=1).min() - 200
    app.panel.show_trail.value = True
    assert len(writer.view.trail.points) == app.state + 1  # the followed hand's path alone, one step per state
    app.panel.show_trail.value = False


def test_a_robot_exports_its_denoising_as_a_gif_and_a_labelled_png(app, tmp_path):
    """A robot exports its denoising as the planar arm does: the skeletons are drawn as the viewer's camera sees
    them, the followed one in the viewer's blue."""
    import imageio.v2 as imageio
    from viz_helpers import read_png

    assert not app.panel.export_button.disabled
    gif, png = app.export(tmp_path)
    frames = imageio.mimread(gif)
    assert len(frames) > 2 and not np.array_equal(frames[0], frames[-1])
    image = read_png(png.read_bytes())
    blue = (image[..., 2] > 150) & (image[..., 0] < 120)  # the followed skeleton (the viewer's accent)
    red = (image[..., 0] > 180) & (image[..., 1] < 80) & (image[..., 2] < 80)  # the target's cross
    assert blue.sum() > 50 and red.sum() > 20
    assert "mm" in gif.name or gif.name.startswith("ikdp_ddpm_K")


def test_the_robots_meshes_skeletons_and_hand_are_drawn_from_the_same_state(app):
    """Once, at the last state the meshes and hand showed the returned (refined) pose while the
    skeletons showed the sampler's last state: stray skeleton lines."""
    from ikdp_viz.chain_scene import gizmo_pose

    app.panel.refine.value = True
    settle(app)
    view, writer = app.solved.view, app.writer
    assert not np.allclose(view.final_joint_values, view.joint_values[-1])  # the two differ for this model
    for state in (view.num_states // 2, view.num_states - 1):
        app.show_state(state)
        highlight = app.highlight_index()
        skeleton = writer.view.skeletons.points.reshape(view.num_samples, -1, 2, 3)[highlight]
        hand, _ = gizmo_pose(app.solver.arm, view.joint_values[state, highlight])
        assert np.allclose(writer.view.hand.position, hand, atol=1e-5)
        assert np.allclose(skeleton[-1, 1], writer.view.hand.position, atol=1e-4)  # the skeleton ends at the hand


def test_a_drag_shows_a_fast_preview_first_then_the_full_solve_and_says_which():
    """A robot's drag answered in 0.4-1.0 s with DDPM alone, so a fast DPM-Solver++ solve is drawn
    first, the readout naming it, and the DDPM solve replaces it."""
    from viz_helpers import shipped_solver_or_skip

    # a robot model without a student (one with a student previews with it: tests/test_viz_student.py)
    with running_app(shipped_solver_or_skip("ikdp_z1"), animation_seconds=0.0) as app:
        settle(app)
        shown = solves_shown_by_a_robot_drag(app)
        moved = app.target
        kinds = [(solved.request.sampler, solved.preview_of) for solved in shown]
        assert kinds == [("dpmpp2m", "ddpm"), ("ddpm", None)]  # the preview first, then the full solve
        assert app.solved.request.sampler == "ddpm" and "Fast preview" not in app.panel.readout_text.content
        app.writer.ask(solved=(shown[0], True))
        app.writer.flush()
        assert "**Fast preview** (dpmpp2m, 5 steps) while the ddpm solve runs" in app.panel.readout_text.content
        before = len(shown)
        app.move_target(moved + np.array([0.02, 0, 0, 0, 0, 0, 0]))  # a move made in one go animates: no preview
        settle(app)
        assert [solved.preview_of for solved in shown[before:]] == [None]


def test_a_robot_compares_two_samplers_from_the_same_noise(app):
    """A robot gets the second sampler's skeletons beside it, each side's title just over its own final poses,
    the chart its curve, and one camera over both."""
    from ikdp_viz.camera import camera_fit_3d

    alone = np.asarray(app.server.initial_camera.position).copy()
    assert app.panel.learn.compare.visible
    app.panel.learn.compare.value = "dpmpp2m"
    settle(app)
    compare, view = app.solved.compare, app.solved.view
    assert compare is not None and compare.num_samples == view.num_samples
    nodes = app.writer.stage.compare
    assert nodes.shown and len(nodes.nodes["skeletons"].points) == view.num_samples * compare.num_joints
    reach = float(app.solver.arm.reach[1])
    for title, points in (("main_title", view.points[-1]), ("title", compare.points[-1] + nodes.shift)):
        position, joints = np.asarray(nodes.nodes[title].position), points.reshape(-1, 3)
        low, high = joints.min(axis=0), joints.max(axis=0)
        assert np.all((low[:2] <= position[:2]) & (position[:2] <= high[:2])), (title, position, low, high)
        assert 0.0 < position[2] - high[2] <= 0.15 * reach, (title, position[2], high[2], reach)  # just above them
    assert len(app.panel.plot.data) == 5  # t, median, highlighted, now, and the compared sampler
    both = np.asarray(app.server.initial_camera.position)
    assert not np.allclose(both, alone)  # framed over both
    app.panel.learn.compare.value = "off"
    settle(app)
    assert not nodes.shown
    center, reach = app.writer.view.center, app.writer.view.reach
    assert np.allclose(app.server.initial_camera.position, camera_fit_3d(center, reach)[0])


def test_a_robot_offers_no_noise_it_button_which_would_do_nothing(app):
    # the forward process is drawn for a planar arm's poses; a robot's button would do nothing when clicked
    assert not app.panel.teach.noise_it.visible
    assert app.noise_it() is None
