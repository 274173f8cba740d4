"""The viewer's Constraints folder: locks, obstacles, staying near, follow mode, the coloured overlay."""

from __future__ import annotations

import numpy as np
import pytest
from viz_helpers import drag_gizmo, running_app, settle

import ikdp
from ikdp_viz.constraint_scene import HOLDS, VIOLATES, first_holding_state, follow_choice, overlay_segments

K = 8


def test_the_overlay_colours_each_state_by_whether_it_holds():
    points = np.zeros((3, 4, 2))  # 3 states of a 3-link planar pose
    points[:, :, 0] = np.arange(4)
    segments, colors = overlay_segments(points, np.array([0.5, 0.02, 0.0]))
    assert segments.shape == (9, 2, 3) and colors.shape == (9, 2, 3)
    assert (colors[:3] == VIOLATES).all() and (colors[3:6] == VIOLATES).all() and (colors[6:] == HOLDS).all()
    assert first_holding_state(np.array([0.5, 0.0, 0.2, 0.0, 0.0])) == 3
    assert first_holding_state(np.array([0.0, 0.0, 0.3])) is None


def test_follow_keeps_the_nearest_sample_that_reaches():
    arm = ikdp.PlanarArm([1.0, 1.0])
    finals = np.array([[0.0, 1.0], [3.0, -1.0], [0.05, 1.0]])
    errors = np.array([1e-6, 1e-6, 0.5])  # the third is nearest but misses
    choice, jump = follow_choice(arm, finals, np.array([3.1, -1.0]), errors)
    assert choice == 1 and jump == pytest.approx(0.1)
    assert follow_choice(arm, finals, None, errors) == (0, 0.0)


@pytest.fixture
def app(tiny_checkpoint):
    with running_app(ikdp.load(tiny_checkpoint), solve_now=False, animation_seconds=0.0) as app:
        app.panel.samples.value = K
        settle(app)
        yield app


def test_a_locked_joint_holds_in_every_returned_pose_and_is_reported(app):
    controls = app.constraint_controls
    controls.lock_values[1].value = 0.8
    controls.lock_boxes[1].value = True  # asks for a solve
    settle(app)
    assert np.array_equal(app.solved.final_angles[:, 1], np.full(K, np.float32(0.8)))
    assert app.solved.state_violation.shape == (len(app.solved.view.labels), K)
    assert "holds from state" in controls.readout.content
    assert controls.overlay is not None  # the coloured states are drawn


def test_an_obstacle_dropped_and_dragged_bends_the_solve(app):
    controls = app.constraint_controls
    index = controls.add_obstacle(position=(0.9, 0.6, 0.0), radius=0.4)
    settle(app)
    assert app.solved.request.constraints[0].name == "obstacles"
    assert controls.obstacles[index]["nodes"]  # its gizmo and sphere exist
    controls.move_obstacle(index, (-1.0, -1.0, 0.0))
    settle(app)
    assert np.allclose(app.solved.request.constraints[0].centers, [[-1.0, -1.0]])
    controls.clear_obstacles()
    settle(app)
    assert app.solved.request.constraints == ()


def test_follow_mode_pulls_toward_the_last_pose_and_reads_the_largest_jump(app):
    controls = app.constraint_controls
    controls.follow.value = True
    settle(app)
    for step in range(4):
        drag_gizmo(app, 1.2 + 0.03 * step, 1.0, phase="update")
        settle(app)
        near = [c for c in app.solved.request.constraints if c.name == "near_pose"]
        assert near, "follow mode asks each solve to stay near the last pose"
    assert app.panel.highlight.value != "best"  # the kept sample is the highlighted one
    assert "largest so far" in controls.readout.content
    assert controls.largest_jump >= 0.0


def test_a_robot_gets_the_same_folder_with_its_joint_names_and_spheres(tiny_chain_checkpoint):
    with running_app(ikdp.load(tiny_chain_checkpoint), solve_now=False, animation_seconds=0.0) as app:
        app.panel.samples.value = 4
        settle(app)
        controls = app.constraint_controls
        assert controls.lock_boxes[6].label == "lock panda_joint7"
        controls.lock_values[6].value = 1.0
        controls.lock_boxes[6].value = True
        controls.add_obstacle(position=(0.3, 0.0, 0.4), radius=0.08)
        settle(app)
        assert app.writer.error is None, app.writer.error
        names = [c.name for c in app.solved.request.constraints]
        assert names == ["locked_joints", "obstacles"]
        assert np.all(app.solved.final_angles[:, 6] == np.float32(1.0))
        assert controls.overlay is not None
        with pytest.raises(ValueError, match="outside its limits"):  # the number field's bounds aside
            ikdp.LockedJoints({"panda_joint4": 0.5}).bind(app.solver.arm, 1, 1)
