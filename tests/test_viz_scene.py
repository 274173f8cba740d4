"""The viewer's scene building, as plain arrays: no server, no browser."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
import torch
from viz_helpers import hand_made_result

import ikdp
from ikdp_viz import robot_meshes
from ikdp_viz.planar_scene import (
    LAYER_HEIGHT,
    arm_placement,
    build_view,
    circle_segments,
    clamp_to_workspace,
    error_curves,
    fade_colors,
    grid_segments,
    line_colors,
    nearest_state,
    polyline_segments,
    sample_colors,
    state_labels,
    trail_colors,
    trail_points,
    trail_until,
)
from ikdp_viz.style import ACCENT_DARK, DARK, FAINT


def luminance(colors: np.ndarray) -> np.ndarray:
    return colors.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])


def test_fade_colors_run_from_faint_to_dark_monotonically():
    colors = fade_colors(81)
    assert colors.shape == (81, 3) and colors.dtype == np.uint8
    assert tuple(colors[0]) == FAINT and tuple(colors[-1]) == DARK
    assert (np.diff(colors.astype(int), axis=0) <= 0).all()  # no channel ever lightens
    assert (np.diff(luminance(colors)) <= 0).all()
    assert luminance(colors[-1]) < luminance(colors[40]) < luminance(colors[0])
    accent = fade_colors(10, FAINT, ACCENT_DARK, gamma=1.0)
    assert (np.diff(luminance(accent)) < 0).all()
    assert tuple(fade_colors(1)[0]) == DARK  # a single state is a final pose
    with pytest.raises(ValueError, match="count"):
        fade_colors(0)


def test_clamp_to_workspace_keeps_inside_points_and_projects_outside_ones_radially():
    point, clamped = clamp_to_workspace((1.0, -2.0), 0.0, 4.0)
    assert not clamped and np.array_equal(point, [1.0, -2.0])
    point, clamped = clamp_to_workspace((6.0, 8.0), 0.0, 4.0)
    assert clamped and np.allclose(point, [2.4, 3.2])  # same direction, on the boundary
    point, clamped = clamp_to_workspace((0.0, 0.5), 1.0, 3.0)
    assert clamped and np.allclose(point, [0.0, 1.0])  # inside the inner hole: out to the inner circle
    point, clamped = clamp_to_workspace((0.0, 0.0), 1.0, 3.0)
    assert clamped and np.allclose(point, [1.0, 0.0])
    point, clamped = clamp_to_workspace((4.0, 0.0, 7.0), 0.0, 4.0)  # a gizmo position: z ignored
    assert not clamped and np.array_equal(point, [4.0, 0.0])
    with pytest.raises(ValueError, match="point"):
        clamp_to_workspace((float("nan"), 0.0), 0.0, 4.0)


def test_state_labels_run_from_T_to_zero_for_ddpm_and_ddim():
    assert state_labels(list(range(79, -1, -1))).tolist() == list(range(80, -1, -1))
    assert state_labels([79, 53, 26, 0]).tolist() == [80, 54, 27, 1, 0]
    assert state_labels([79]).tolist() == [80, 0]
    labels = state_labels([79, 53, 26, 0])
    assert nearest_state(labels, 80) == 0 and nearest_state(labels, 0) == 4
    assert nearest_state(labels, 50) == 1 and nearest_state(labels, 2) == 3


def test_build_view_of_a_hand_made_solve_has_closed_form_joints():
    view = build_view(hand_made_result(), (1.0, 1.0), (2.0, 0.0))
    assert view.joints.shape == (3, 2, 3, 2)
    assert (view.num_states, view.num_samples, view.num_links) == (3, 2, 2)
    assert np.allclose(view.joints[0, 0], [[0, 0], [0, 1], [0, 2]], atol=1e-12)
    assert np.allclose(view.joints[0, 1], [[0, 0], [-1, 0], [0, 0]], atol=1e-12)
    assert np.allclose(view.joints[1, 0], [[0, 0], [1, 0], [1, 1]], atol=1e-12)
    assert np.allclose(view.final_joints[1], [[0, 0], [0, 1], [1, 1]], atol=1e-12)
    assert np.allclose(view.tip_error[:, 0], [math.hypot(2, 2), math.hypot(1, 1), 0.0], atol=1e-12)
    assert np.allclose(view.tip_error[-1], [0.0, math.hypot(1, 1)], atol=1e-12)
    assert view.labels.tolist() == [2, 1, 0] and not view.refined and view.best_sample() == 0


def test_build_view_needs_the_trajectory():
    result = hand_made_result()
    result.trajectory = None
    with pytest.raises(ValueError, match="return_trajectory"):
        build_view(result, (1.0, 1.0), (2.0, 0.0))


@pytest.mark.parametrize("refine_steps", [0, 3])
def test_final_pose_is_the_forward_kinematics_of_the_returned_angles(tiny_checkpoint, refine_steps):
    solver = ikdp.load(tiny_checkpoint)
    target = (0.9, 1.3)
    generator = torch.Generator().manual_seed(0)
    out = solver.solve([target], num_samples=5, refine_steps=refine_steps, generator=generator, return_trajectory=True)
    view = build_view(out, solver.lengths, target)
    expected = ikdp.forward_kinematics(out.angles[0].double(), torch.tensor(solver.lengths, dtype=torch.float64))
    assert np.allclose(view.final_joints, expected.numpy(), atol=1e-12)
    assert np.allclose(view.joints[-1], ikdp.forward_kinematics(out.raw_angles[0].double()).numpy(), atol=1e-6)
    assert np.allclose(view.tip_error[-1], out.raw_tip_error[0].numpy(), atol=1e-5)
    assert np.allclose(view.final_tip_error, out.tip_error[0].numpy())
    assert view.refined == (refine_steps > 0)
    assert view.num_states == solver.timesteps + 1 and view.labels[0] == solver.timesteps and view.labels[-1] == 0


def test_polyline_segments_join_consecutive_points_in_order():
    polyline = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    segments = polyline_segments(polyline, z=0.5)
    assert segments.shape == (2, 2, 3)
    assert np.array_equal(segments[0], [[0, 0, 0.5], [1, 0, 0.5]])
    assert np.array_equal(segments[1], [[1, 0, 0.5], [1, 2, 0.5]])
    assert polyline_segments(np.zeros((4, 3, 6, 2))).shape == (4 * 3 * 5, 2, 3)


def test_trail_layers_each_state_above_the_one_before_and_colours_it_by_its_state():
    view = build_view(hand_made_result(), (1.0, 1.0), (2.0, 0.0))
    points = trail_points(view.joints)
    assert points.shape == (3, 2 * 2, 2, 3) and points.dtype == np.float32
    assert np.allclose(points[:, :, :, 2], (np.arange(3) * LAYER_HEIGHT)[:, None, None])
    assert np.allclose(points[2, :2, :, :2], [[[0, 0], [1, 0]], [[1, 0], [2, 0]]])  # sample 0's final polyline
    colors = sample_colors(3, 2, highlight=1)
    per_segment = trail_colors(colors, view.num_links)
    assert per_segment.shape == (3, 4, 2, 3)
    assert (per_segment[1, :2] == colors[1, 0]).all() and (per_segment[1, 2:] == colors[1, 1]).all()
    segments, segment_colors = trail_until(points, per_segment, 0)
    assert segments.shape == (4, 2, 3) and segment_colors.shape == (4, 2, 3)  # the pure-noise poses alone
    segments, _ = trail_until(points, per_segment, 2)
    assert segments.shape == (12, 2, 3)


def test_the_light_trail_keeps_a_fixed_grid_of_states_and_the_current_one():
    states, segments_per_state = 81, 4
    points = np.broadcast_to(
        np.arange(states, dtype=np.float32)[:, None, None, None], (states, segments_per_state, 2, 3)
    )
    colors = np.zeros((states, segments_per_state, 2, 3), np.uint8)
    drawn_states = lambda state: np.unique(trail_until(points, colors, state, most_states=12)[0][..., 0])  # noqa: E731
    # the grid (every 8th state: 81 states in 11) below the current state, from the start: nothing jumps
    assert list(drawn_states(0)) == [0] and list(drawn_states(5)) == [0, 5]
    assert list(drawn_states(20)) == [0, 8, 16, 20] and list(drawn_states(21)) == [0, 8, 16, 21]  # the grid stays put
    assert len(drawn_states(80)) <= 12 and drawn_states(80)[-1] == 80
    assert list(drawn_states(8)) == [0, 8]
    assert len(trail_until(points, colors, 80)[0]) == states * segments_per_state  # no limit: every state


def test_sample_colors_give_the_highlighted_sample_the_accent_ramp():
    colors = sample_colors(5, 3, highlight=2)
    assert colors.shape == (5, 3, 3)
    assert tuple(colors[-1, 0]) == DARK and tuple(colors[-1, 2]) == ACCENT_DARK
    assert (colors[:, 0] == colors[:, 1]).all()
    assert (sample_colors(5, 3, highlight=None) == fade_colors(5)[:, None]).all()


def test_arm_placement_draws_each_link_between_its_joints_and_lifts_the_highlight():
    rng = np.random.default_rng(0)
    lengths = np.array([1.0, 0.5, 1.5])
    headings = torch.tensor(rng.uniform(-math.pi, math.pi, (4, 3)))
    joints = ikdp.forward_kinematics(headings, torch.tensor(lengths)).numpy()  # (K=4, N+1=4, 2)
    placement = arm_placement(joints, raised=2, lift=0.1)
    assert placement.link_segments.shape == (12, 2, 3)
    assert placement.joint_positions.shape == (16, 3) and placement.tip_positions.shape == (4, 3)
    segments = placement.link_segments.reshape(4, 3, 2, 3)
    assert np.allclose(segments[:, :, 0, :2], joints[:, :-1], atol=1e-12)
    assert np.allclose(segments[:, :, 1, :2], joints[:, 1:], atol=1e-12)
    assert np.allclose(np.linalg.norm(segments[..., 1, :] - segments[..., 0, :], axis=-1), lengths)  # bone lengths
    heights = placement.joint_positions[:, 2].reshape(4, 4)
    assert np.allclose(heights[2], 0.1) and np.allclose(heights[[0, 1, 3]], 0.0)  # the highlighted arm on top
    assert np.allclose(segments[2, ..., 2], 0.1) and np.allclose(segments[[0, 1, 3], ..., 2], 0.0)
    assert np.allclose(placement.tip_positions[:, :2], joints[:, -1])


def test_grid_segments_cover_the_square_with_a_section_line_every_section():
    points, sections = grid_segments(2.0, 0.5, 1.0, z=-0.1)
    assert points.shape == (2 * 9, 2, 3) and sections.shape == (18,)
    assert np.allclose(points[..., 2], -0.1) and np.abs(points[..., :2]).max() == 2.0
    vertical = points[:9]
    assert np.allclose(vertical[:, 0, 0], vertical[:, 1, 0]) and np.allclose(vertical[:, 0, 0], np.arange(-2, 2.1, 0.5))
    assert sections[:9].tolist() == [True, False, True, False, True, False, True, False, True]  # x = -2, -1, 0, 1, 2


def test_circle_segments_lie_on_the_circle():
    segments = circle_segments(4.0, count=64, z=-0.1)
    assert segments.shape == (64, 2, 3)
    assert np.allclose(np.linalg.norm(segments[..., :2], axis=-1), 4.0)
    assert np.allclose(segments[1:, 0], segments[:-1, 1]) and np.allclose(segments[0, 0], segments[-1, 1])
    assert np.allclose(segments[..., 2], -0.1)


def test_error_curves_run_in_ascending_t_with_one_marker_at_the_current_state():
    view = build_view(hand_made_result(), (1.0, 1.0), (2.0, 0.0))
    t, median, chosen, marker = error_curves(view, highlight=1, state=1)
    assert t.tolist() == [0.0, 1.0, 2.0]  # state 2 is t = 0
    assert np.isfinite(marker).sum() == 1 and marker[1] == chosen[1] == pytest.approx(np.log10(view.tip_error[1, 1]))
    assert np.allclose(median[::-1], np.log10(np.maximum(np.median(view.tip_error, axis=1), 1e-6)))
    assert np.isfinite(chosen).all() and chosen.min() >= -6  # a zero error is charted at the floor, not -inf


def test_meshes_are_sized_to_the_arm_and_closed():
    sizes = robot_meshes.ArmSizes.for_lengths((2.0, 2.0))
    assert sizes.tip > sizes.joint > 0 and sizes.cross > sizes.joint
    assert robot_meshes.base_mesh(sizes.base).is_watertight and robot_meshes.base_mesh(sizes.base).bounds[1, 2] <= 0
    assert (
        robot_meshes.sphere_mesh(sizes.joint).is_watertight and len(robot_meshes.sphere_mesh(sizes.joint).faces) == 20
    )
    cross = robot_meshes.cross_mesh(sizes.cross)
    assert np.allclose(cross.bounds[:, 2], [-0.011 * sizes.cross, 0.011 * sizes.cross])  # flat, centred: the
    # scene writer lifts it (scene_writer.over_the_point)
    assert np.isclose(np.abs(cross.vertices[:, :2]).max(), sizes.cross * math.sqrt(0.5) + 0.11 * sizes.cross, rtol=0.2)


def test_importing_the_viewer_does_nothing_and_scene_code_never_imports_viser():
    code = (
        "import sys, threading, io, contextlib\n"
        "before = threading.active_count()\n"
        "out = io.StringIO()\n"
        "with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):\n"
        "    import ikdp_viz, ikdp_viz.planar_scene, ikdp_viz.robot_meshes, ikdp_viz.readouts\n"
        "    import ikdp_viz.solve_worker, ikdp_viz.solving\n"
        "    assert 'viser' not in sys.modules, 'scene-building code imported viser'\n"
        "    import ikdp_viz.panel, ikdp_viz.solving, ikdp_viz.scene_writer, ikdp_viz.app, ikdp_viz.__main__\n"
        "    import ikdp_viz.screenshot\n"
        "assert out.getvalue() == '', out.getvalue()\n"
        "assert threading.active_count() == before, threading.enumerate()\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_line_colors_send_the_linear_value_of_the_colour_meant():
    sent = line_colors(np.array([[0, 0, 0], [28, 28, 28], [255, 255, 255], [20, 90, 210]], np.uint8))
    assert sent[0].tolist() == [0, 0, 0] and sent[2].tolist() == [255, 255, 255]
    assert sent[1].tolist() == [3, 3, 3]  # the page's sRGB encoding of 3 / 255 shows 28 again
    encoded = 255 * np.where(sent / 255 <= 0.0031308, 12.92 * sent / 255, 1.055 * (sent / 255) ** (1 / 2.4) - 0.055)
    assert np.abs(encoded[3] - [20, 90, 210]).max() < 6  # uint8 steps in linear space are coarse near black


@pytest.mark.parametrize("aspect", [0.3, 1280 / 1700, 1.0, 1.6, 3.0])
def test_the_field_of_view_sees_across_at_least_as_much_as_a_square_canvas(aspect):
    """A tall canvas's camera sees as far to the sides as viser's default sees up and down: the reach fits."""
    from ikdp_viz.camera import VERTICAL_FOV, field_of_view

    fov = field_of_view(aspect)
    across, up = np.tan(fov / 2) * aspect, np.tan(fov / 2)
    assert across >= np.tan(VERTICAL_FOV / 2) - 1e-12 and up >= np.tan(VERTICAL_FOV / 2) - 1e-12
    assert min(across, up) == pytest.approx(np.tan(VERTICAL_FOV / 2))  # no wider than needed


def test_the_field_of_view_refuses_a_canvas_with_no_width():
    from ikdp_viz.camera import field_of_view

    with pytest.raises(ValueError, match="aspect"):
        field_of_view(0.0)
