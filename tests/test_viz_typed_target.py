"""A target typed in the panel or given on the command line (ikdp_viz/typed_target.py), planar and robot."""

from __future__ import annotations

import numpy as np
import pytest
from viz_helpers import running_app, settle

import ikdp
from ikdp_viz.typed_target import point_from_numbers, pose_from_numbers, roll_pitch_yaw_degrees, rotation_wxyz


def test_roll_pitch_yaw_in_degrees_round_trips_and_means_x_then_y_then_z():
    assert np.allclose(rotation_wxyz((0, 0, 90)), [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])  # yaw: about z
    assert np.allclose(rotation_wxyz((180, 0, 0)), [0, 1, 0, 0], atol=1e-12)  # roll: about x
    angles = (10.0, -20.0, 30.0)
    assert np.allclose(roll_pitch_yaw_degrees(rotation_wxyz(angles)), angles)


def test_numbers_become_a_target_for_each_kind_of_arm_or_a_one_line_error():
    current = np.array([0.3, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0])
    assert np.allclose(point_from_numbers((1.0, 2.0)), [1.0, 2.0])
    kept = pose_from_numbers((0.4, 0.1, 0.2), target_dim=7, current=current)
    assert np.allclose(kept, [0.4, 0.1, 0.2, 0.0, 1.0, 0.0, 0.0])  # a position alone keeps the rotation
    turned = pose_from_numbers((0.4, 0.1, 0.2, 0, 0, 90), target_dim=7, current=current)
    assert np.allclose(turned[3:], rotation_wxyz((0, 0, 90)))
    quaternion = pose_from_numbers((0.4, 0.1, 0.2, 1, 0, 0, 0), target_dim=7, current=current)
    assert np.allclose(quaternion, [0.4, 0.1, 0.2, 1, 0, 0, 0])
    for values, kind, dim, message in (
        ((1.0,), "planar", 2, "planar arm's target is x y"),
        ((0.1, 0.2, 0.3, 4.0), "chain", 7, "roll pitch yaw"),
        ((0.1, 0.2, 0.3, 0, 0, 0), "chain", 3, "position x y z"),
        ((np.nan, 1.0), "planar", 2, "finite"),
    ):
        with pytest.raises(ValueError, match=message):
            if kind == "planar":
                point_from_numbers(values)
            else:
                pose_from_numbers(values, target_dim=dim, current=current)


def test_a_target_typed_in_the_planar_panel_is_solved_and_the_fields_follow_drags(tiny_checkpoint):
    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0, target=(1.0, 0.5)) as app:
        settle(app)
        inputs = app.panel.learn.target
        assert inputs.xy.visible and not inputs.position_mm.visible and tuple(inputs.xy.value) == (1.0, 0.5)
        inputs.xy.value = (-0.8, 1.1)
        app.move_typed_target()  # what the "Solve this target" button does
        settle(app)
        assert np.allclose(app.solved.view.target, [-0.8, 1.1]) and np.allclose(app.gizmo.position[:2], [-0.8, 1.1])
        app.move_target((0.4, -0.9))
        settle(app)
        assert tuple(inputs.xy.value) == (0.4, -0.9)  # the fields show the target solved
        inputs.xy.value = (50.0, 0.0)  # beyond reach: pulled onto the boundary, as a drag is
        app.move_typed_target()
        settle(app)
        assert np.isclose(np.hypot(*app.solved.view.target), app.solver.reach[1])
        assert "Clamped" in app.panel.target_text.content


def test_a_robot_target_typed_as_position_and_roll_pitch_yaw_is_solved(tiny_chain_checkpoint):
    solver = ikdp.load(tiny_chain_checkpoint)
    with running_app(solver, animation_seconds=0.0) as app:
        app.panel.samples.value = 2
        settle(app)
        inputs = app.panel.learn.target
        assert inputs.position_mm.visible and inputs.rotation_deg.visible and not inputs.xy.visible
        start = app.target.copy()
        assert np.allclose(np.asarray(inputs.position_mm.value) / 1000, start[:3], atol=1e-4)
        position = start[:3] + (0.0, 0.05, -0.05)
        inputs.position_mm.value = tuple(1000 * position)
        inputs.rotation_deg.value = (170.0, 5.0, -30.0)
        app.move_typed_target()
        settle(app)
        solved = app.solved.request.target
        assert np.allclose(solved[:3], position, atol=1e-6)
        assert np.allclose(np.abs(solved[3:] @ rotation_wxyz((170.0, 5.0, -30.0))), 1.0, atol=1e-9)  # same rotation
        assert np.allclose(app.gizmo.wxyz, solved[3:]) and np.allclose(app.gizmo.position, solved[:3])


def test_the_command_line_target_opens_a_robot_there(tiny_chain_checkpoint):
    from ikdp_viz.__main__ import VizConfig, apply_settings, config_target

    solver = ikdp.load(tiny_chain_checkpoint)
    config = VizConfig(target=(0.4, 0.1, 0.5, 180.0, 0.0, 0.0), samples=2)
    with running_app(solver, solve_now=False, animation_seconds=0.0) as app:
        apply_settings(app, config)
        settle(app)
        assert np.allclose(app.solved.request.target, config_target(solver, config), atol=1e-6)
        assert np.allclose(np.abs(app.solved.request.target[3:] @ rotation_wxyz((180, 0, 0))), 1.0)
    with pytest.raises(ValueError, match="roll pitch yaw"):
        config_target(solver, VizConfig(target=(0.4, 0.1)))
