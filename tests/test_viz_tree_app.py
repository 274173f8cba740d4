"""The 3-D viewer on a kinematic tree (the shipped Unitree G1: waist and two arms, both hands), in-process on a real
viser server: one gizmo, hand frame, trail and readout per hand; dragging one hand's gizmo keeps the other's target.

K = 4, DPM-Solver++(2M) in 10 steps and no animation: every check reads a finished frame in a second or so.
"""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from viz_helpers import running_app, settle, shipped_solver_or_skip

from ikdp_viz.chain_kind import TreeKind
from ikdp_viz.chain_scene import ChainView, skeleton_segments
from ikdp_viz.readouts import miss_text
from ikdp_viz.robot_view import RobotView

K = 4
HANDS = ("left_rubber_hand", "right_rubber_hand")


@pytest.fixture(scope="module")
def g1():
    return shipped_solver_or_skip("ikdp_g1")


@pytest.fixture
def app(g1):
    with running_app(g1, solve_now=False, animation_seconds=0.0) as app:
        app.panel.sampler.value = "dpmpp2m"
        app.panel.steps.value = 10
        app.panel.samples.value = K  # asks for a solve of the first target
        settle(app)
        yield app


def drag(app, hand: int, position, phase: str = "end") -> None:
    """Do what viser does when the page drags hand `hand`'s gizmo: set its position, then fire its callback."""
    import viser

    gizmo = app.writer.view.gizmos[hand]
    gizmo._impl.position = np.asarray(position, float)
    event = viser.TransformControlsEvent(client=None, client_id=None, target=gizmo, phase=phase)
    asyncio.run_coroutine_threadsafe(app.on_gizmo_update(event), app.server.get_event_loop()).result(timeout=10)
    settle(app)


def test_the_tree_is_drawn_with_its_meshes_one_gizmo_and_one_hand_frame_per_hand(app):
    view, solved = app.writer.view, app.solved.view
    arm, kind = app.solver.arm, TreeKind()
    assert isinstance(view, RobotView) and tuple(solved.effector_names) == HANDS
    assert len(view.robot_meshes) > 0 or "No meshes" in app.panel.model_text.content
    # one polyline per chain, base to hand: K * (P - E) segments, none from the left hand to the right arm
    assert view.skeletons.points.shape == (K * (solved.points.shape[2] - 2), 2, 3)
    shown = solved.points[-1]  # (K, P, 3) the state on screen: the last
    np.testing.assert_allclose(view.skeletons.points, skeleton_segments(shown, solved.polylines), atol=1e-6)
    left_hand, right_start = shown[0, solved.polylines[0] - 1], shown[0, solved.polylines[0]]
    starts, ends = view.skeletons.points[:, 0], view.skeletons.points[:, 1]
    assert not (np.isclose(starts, left_hand).all(-1) & np.isclose(ends, right_start).all(-1)).any()
    assert [gizmo.name for gizmo in view.gizmos] == [f"/targets/{name}" for name in HANDS]
    rows = kind.pose_rows(arm, app.target)  # (2, 7)
    for gizmo, row in zip(view.gizmos, rows, strict=True):
        np.testing.assert_allclose(gizmo.position, row[:3], atol=1e-6)
    positions, _ = kind.hand_poses(arm, solved.final_joint_values[app.highlight_index()])
    for hand, position in zip(view.hands, positions, strict=True):
        np.testing.assert_allclose(hand.position, position, atol=1e-6)
    assert np.linalg.norm(positions[0] - positions[1]) > 0.1  # two hands, not one frame drawn twice


def test_the_readouts_and_legend_name_each_hand(app):
    app.panel.show_trail.value = True
    app.show_state(5)
    frame = app.writer.frame
    readout, target = app.panel.readout_text.content, app.panel.target_text.content
    for name in HANDS:
        assert name in target
        (line,) = [line for line in readout.splitlines() if line.startswith(f"{name}:")]
        assert "mm" in line and "°" in line and "now" in line and "at t = 0" in line
    texts = [entry.text for entry in frame.legend]
    assert any("one gizmo per hand" in text for text in texts), texts
    assert any(text.startswith("hand frames") for text in texts), texts
    assert any(text.startswith("trail") and "hands' paths" in text for text in texts), texts
    # the trail: each hand's path of the highlighted sample, two segments per state up to the one shown
    assert app.writer.view.trail.points.shape == (2 * (5 + 1), 2, 3)


def test_dragging_one_hands_gizmo_moves_its_target_alone_and_solves_both(app):
    arm, kind = app.solver.arm, TreeKind()
    before = kind.pose_rows(arm, app.target)
    moved = before[1, :3] + np.array([0.0, -0.04, 0.05])
    drag(app, 1, moved)
    after = kind.pose_rows(arm, app.target)
    np.testing.assert_array_equal(after[0], before[0])  # the left hand's target kept, to the bit
    np.testing.assert_allclose(after[1, :3], moved, atol=1e-9)
    np.testing.assert_allclose(after[1, 3:], before[1, 3:], atol=1e-9)
    assert np.array_equal(app.solved.request.target, app.target)  # the solve on screen is of both hands' targets
    np.testing.assert_allclose(app.writer.view.gizmos[0].position, before[0, :3], atol=1e-9)


def test_a_hand_out_of_reach_is_named(app):
    arm, kind = app.solver.arm, TreeKind()
    rows = kind.pose_rows(arm, app.target)
    rows[0, :3] = (0.2, 1.6, 0.1)  # the left hand's target two metres out
    app.move_target(kind.flat_target(arm, rows))
    settle(app)
    assert "out of reach: left_rubber_hand" in app.panel.target_text.content
    miss = [line for line in app.panel.readout_text.content.splitlines() if line.startswith("**Out of reach**")]
    assert miss and "left_rubber_hand" in miss[0].split(";")[0] and "right_rubber_hand" not in miss[0].split(";")[0]
    drag(app, 1, rows[1, :3] + (0.0, 0.0, 0.03))  # the other hand's drag keeps the left one's target out of reach
    assert "out of reach: left_rubber_hand" in app.panel.target_text.content
    assert "**Out of reach**: the target of left_rubber_hand" in app.panel.readout_text.content


def tree_view(position_errors, rotation_errors) -> ChainView:
    """A one-state, one-sample view of two hands with these final errors (m, rad)."""
    position, rotation = np.array([position_errors]), np.array([rotation_errors])  # (K=1, E=2)
    zeros = np.zeros((1, 1))
    return ChainView(
        target=np.zeros(14), labels=np.array([0]), joint_values=np.zeros((1, 1, 3)), points=np.zeros((1, 1, 4, 3)),
        position_error=zeros, rotation_error=zeros, final_joint_values=np.zeros((1, 3)),
        final_points=np.zeros((1, 4, 3)), final_position_error=position.max(-1), final_rotation_error=rotation.max(-1),
        refined=False, effector_names=HANDS, polylines=(2, 2), final_effector_position_error=position,
        final_effector_rotation_error=rotation,
    )  # fmt: skip


def test_reached_means_every_hand_within_a_millimetre_and_a_degree(g1):
    degree = np.radians(1.0)
    assert miss_text(tree_view([0.0009, 0.0009], [0.9 * degree, 0.9 * degree]), g1.arm, beyond_reach=False) is None
    text = miss_text(tree_view([0.0009, 0.0009], [0.9 * degree, 1.5 * degree]), g1.arm, beyond_reach=False)
    assert text.startswith("**No sample reaches the targets**") and "right_rubber_hand by 0.9 mm / 1.50°" in text
    assert "left_rubber_hand" not in text
    far = miss_text(tree_view([0.3, 0.0005], [0.0, 0.0]), g1.arm, beyond_reach=np.array([True, False]))
    assert far.startswith("**Out of reach**: the target of left_rubber_hand") and "right_rubber_hand" not in far


def test_polylines_of_a_tree_are_cut_between_its_chains():
    points = np.arange(2 * 5 * 3, dtype=float).reshape(2, 5, 3)  # two samples, chains of 3 and 2 points
    segments = skeleton_segments(points, (3, 2))
    assert segments.shape == (2 * 3, 2, 3)
    np.testing.assert_array_equal(segments[2], points[0, 3:5])  # the second chain's one segment
    assert skeleton_segments(points).shape == (2 * 4, 2, 3)  # one polyline: every consecutive pair
