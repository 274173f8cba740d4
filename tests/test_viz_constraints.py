"""The viewer's Constraints folder: locks, obstacles, staying near, follow mode, the coloured overlay, partial
targets of a pose model, every sample coloured by constraint."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from viz_helpers import drag_gizmo, running_app, settle

import ikdp
from ikdp.rotations import quaternion_to_matrix
from ikdp_viz.chain_kind import GHOST_OPACITY, VIOLATING_GHOST_OPACITY
from ikdp_viz.constraint_scene import build_constraints, first_holding_state, holds, overlay_segments, sample_tints
from ikdp_viz.style import HOLDS, HOLDS_FAINT, HOLDS_OTHERS, VIOLATES, VIOLATES_FAINT, VIOLATES_OTHERS

K = 8


def test_the_overlay_colours_each_state_by_whether_it_holds():
    points = np.zeros((3, 4, 2))  # 3 states of a 3-link planar pose
    points[:, :, 0] = np.arange(4)
    segments, colors = overlay_segments(points, np.array([0.5, 0.02, 0.0]))
    assert segments.shape == (9, 2, 3) and colors.shape == (9, 2, 3)
    assert (colors[:6] == VIOLATES_FAINT).all() and (colors[6:] == HOLDS_FAINT).all()
    assert first_holding_state(np.array([0.5, 0.0, 0.2, 0.0, 0.0])) == 3
    assert first_holding_state(np.array([0.0, 0.0, 0.3])) is None


def test_every_sample_is_tinted_by_its_own_violation_the_highlighted_one_in_full():
    violation = np.array([[0.5, 0.0, 0.3], [0.0, 0.2, 0.0]])  # 2 states of K = 3
    tints = sample_tints(violation, highlight=2)
    assert tints.shape == (2, 3, 3) and tints.dtype == np.uint8
    assert (tints[0, 0] == VIOLATES_OTHERS).all() and (tints[0, 1] == HOLDS_OTHERS).all()
    assert (tints[1, 0] == HOLDS_OTHERS).all() and (tints[1, 1] == VIOLATES_OTHERS).all()
    assert (tints[0, 2] == VIOLATES).all() and (tints[1, 2] == HOLDS).all()


@pytest.fixture
def app(tiny_checkpoint):
    with running_app(ikdp.load(tiny_checkpoint), solve_now=False, animation_seconds=0.0) as app:
        app.panel.samples.value = K
        settle(app)
        yield app


def test_a_locked_joint_holds_in_every_returned_pose_and_is_reported(app):
    controls = app.constraint_controls
    controls.lock_values[1].value = 45.0  # degrees
    controls.lock_boxes[1].value = True  # asks for a solve
    settle(app)
    assert np.array_equal(app.solved.final_angles[:, 1], np.full(K, np.float32(np.radians(45.0))))
    assert app.solved.state_violation.shape == (len(app.solved.view.labels), K)
    assert "holds from state" in controls.readout.content
    assert controls.overlay is not None  # the coloured states are drawn


def test_every_sample_on_screen_is_coloured_by_constraint_and_counted(app):
    controls = app.constraint_controls
    controls.add_obstacle(position=(0.9, 0.6, 0.0), radius=0.5)
    settle(app)
    violation = app.solved.state_violation  # (S+1, K)
    writer = app.writer
    for state in (0, len(violation) // 2, len(violation) - 1):
        app.show_state(state)
        met = holds(violation[state])
        assert f"hold** for {int(met.sum())} of {K} samples at this step" in app.panel.readout_text.content
        expected = np.where(met[:, None], np.array(HOLDS_OTHERS), np.array(VIOLATES_OTHERS))
        others = np.arange(K) != app.highlight_index()
        assert np.array_equal(writer.frame.palette.arms[state][others], expected[others])  # each arm's own colour
    assert "constraints hold at the step shown" in app.panel.learn.legend.content
    controls.color_states.value = False  # back to the grey samples and the blue highlighted one
    settle(app)
    assert not np.isin(writer.frame.palette.arms[-1], [HOLDS_OTHERS, VIOLATES_OTHERS]).all(axis=-1).any()
    assert "(green" not in app.panel.readout_text.content and controls.overlay is None
    assert "constraints hold" not in app.panel.learn.legend.content


def test_a_planar_model_offers_no_partial_target(app):
    assert app.constraint_controls.target_kind is None
    with pytest.raises(ValueError, match="target kind"):
        build_constraints({}, [], None, planar=True, target_kind="position only")


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


def test_follow_mode_steps_from_the_last_pose_and_reads_the_largest_jump(app):
    controls = app.constraint_controls
    controls.follow.value = True
    settle(app)
    for step in range(4):
        drag_gizmo(app, 1.2 + 0.03 * step, 1.0, phase="update")
        settle(app)
        assert app.solved.followed is not None, "follow mode solves each target by tracking's step, from the last pose"
    assert app.panel.highlight.value != "best"  # the kept sample is the highlighted one
    assert "largest so far" in controls.readout.content
    assert controls.largest_jump >= 0.0


def test_a_robot_gets_the_same_folder_with_its_joint_names_and_spheres(tiny_chain_checkpoint):
    with running_app(ikdp.load(tiny_chain_checkpoint), solve_now=False, animation_seconds=0.0) as app:
        app.panel.samples.value = 4
        settle(app)
        controls = app.constraint_controls
        assert controls.lock_boxes[6].label == "lock panda_joint7"
        controls.lock_values[6].value = 57.3  # degrees
        controls.lock_boxes[6].value = True
        controls.add_obstacle(position=(0.3, 0.0, 0.4), radius=0.08)
        settle(app)
        assert app.writer.error is None, app.writer.error
        names = [c.name for c in app.solved.request.constraints]
        assert names == ["locked_joints", "obstacles"]
        assert np.all(app.solved.final_angles[:, 6] == np.float32(np.radians(57.3)))
        assert controls.overlay is not None
        # the see-through robots that break a constraint at the step shown are drawn denser than those that hold
        writer = app.writer
        violation = app.solved.state_violation
        assert not holds(violation[0]).all()  # the noise at t = T: some robots break the lock
        for state in (0, len(violation) - 1):
            app.show_state(state)
            factors = writer.view.ghosts[0].batched_opacities
            met = holds(violation[state])
            assert np.allclose(factors[~met], 1.0)  # the node's full VIOLATING_GHOST_OPACITY
            assert np.allclose(factors[met], GHOST_OPACITY / VIOLATING_GHOST_OPACITY)
        assert "those see-through robots denser" in app.panel.learn.legend.content
        with pytest.raises(ValueError, match="outside its limits"):  # the number field's bounds aside
            ikdp.LockedJoints({"panda_joint4": 0.5}).bind(app.solver.arm, 1, 1)


def test_a_pose_model_solves_a_partial_target_and_shows_what_it_asks(tiny_chain_checkpoint):
    with running_app(ikdp.load(tiny_chain_checkpoint), solve_now=False, animation_seconds=0.0) as app:
        app.panel.samples.value = 4
        settle(app)
        controls, writer = app.constraint_controls, app.writer
        assert controls.target_kind.value == "full pose" and not writer.view.gizmo.disable_rotations
        controls.target_kind.value = "position only"
        settle(app)
        assert [c.name for c in app.solved.request.constraints] == ["position_only"]
        assert writer.view.gizmo.disable_rotations  # the gizmo's rotation asks nothing: its rings are hidden
        view = app.solved.view
        assert view.rotation_measure == "none" and not view.rotation_error.any()
        assert "Position only" in app.panel.readout_text.content and "°" not in app.panel.readout_text.content
        assert app.solved.state_violation is None  # nothing to hold or fail: the errors say how well it went
        controls.target_kind.value = "free z axis"
        settle(app)
        free = app.solved.request.constraints[0]
        assert free.name == "free_axis" and tuple(free.axis) == (0.0, 0.0, 1.0)
        assert not writer.view.gizmo.disable_rotations and controls.target_marks is not None  # the axis is drawn
        assert controls.target_marks.name == "/target/free_axis"  # a child of the gizmo: it turns with it
        segments = controls.target_marks.points
        assert np.allclose(np.cross(segments[0, 1] - segments[0, 0], [0, 0, 1]), 0)  # along the hand's z
        view = app.solved.view
        target = app.solved.request.target
        arm = app.solver.arm
        rotation, _ = arm.end_effector_frame(torch.as_tensor(view.final_joint_values))
        reached = rotation.numpy()[:, :, 2]  # the hands' z axes
        asked = quaternion_to_matrix(torch.as_tensor(target[3:]))[:, 2].numpy()
        angles = np.arccos(np.clip(reached @ asked, -1, 1))
        assert np.allclose(view.final_rotation_error, angles, atol=1e-4)  # the axis's angle, not the rotation's
        assert "(z axis)" in app.panel.readout_text.content
        assert "free z axis: any turn about it counts" in app.panel.learn.legend.content
        controls.lock_boxes[6].value = True  # the other constraints keep working beside it
        controls.follow.value = True
        settle(app)
        names = sorted(c.name for c in app.solved.request.constraints)
        assert names == ["free_axis", "locked_joints"] and app.solved.followed is not None  # tracking's own pull
        assert np.all(app.solved.final_angles[:, 6] == np.float32(np.radians(controls.lock_values[6].value)))
        controls.target_kind.value = "full pose"
        settle(app)
        assert controls.target_marks is None and app.solved.view.rotation_measure == "rotation"


@pytest.mark.parametrize("mode", ["follow", "stay_near"])
def test_a_pulled_solve_still_reaches_the_target_or_says_it_was_dropped(mode):
    """Typed targets 0.1 apart drifted a pulled arm 0.15 bone lengths short while the readout said every constraint
    held: staying near, the pull that misses is dropped and said; following, tracking's step reaches each target."""
    from viz_helpers import shipped_solver_or_skip

    from ikdp_viz.solving import REACH_FRACTION

    solver = shipped_solver_or_skip("ikdp_n4")
    with running_app(solver, target=(-1.5, 2.0), animation_seconds=0.0) as app:
        settle(app)
        getattr(app.constraint_controls, mode).value = True
        settle(app)
        dropped = 0
        for x in np.arange(-1.4, -0.15, 0.1):
            app.move_target((x, 2.0))
            settle(app)
            kept = app.highlight_index()
            assert app.solved.view.final_error[kept] < REACH_FRACTION * solver.arm.span, (x, kept)
            assert "Constraints hold" not in app.panel.readout_text.content  # a pull is no constraint
            dropped += app.solved.pull_missed is not None
            if app.solved.pull_missed is not None:
                assert "without the pull" in app.constraint_controls.readout.content
        if mode == "stay_near":
            assert dropped > 0  # the pull did miss on this path (0.15 away by its end), so the rule was exercised
        else:
            assert dropped == 0  # tracking's step keeps the last pose moved onto the target, no pull to drop


def test_lock_fields_are_degrees_within_the_joints_limits_and_any_angle_wraps():
    """The "θ1 value" took 90 and used 90 rad; a robot's lock fields were radians beside targets
    in degrees, and a value past a limit was used as typed."""
    from ikdp_viz.typed_target import heading_lock_fields, joint_lock_fields

    planar = heading_lock_fields(ikdp.PlanarArm([1.0, 1.0]))
    assert planar[0].label == "θ1 (°)" and planar[0].wraps
    assert planar[0].joint_value(90.0) == (pytest.approx(np.pi / 2), None)
    value, note = planar[0].joint_value(270.0)
    assert value == pytest.approx(-np.pi / 2) and "wrapped" in note
    panda = joint_lock_fields(ikdp.load_robot("panda"))
    limits = np.degrees(ikdp.load_robot("panda").joint_limits.numpy())
    assert panda[3].label == "panda_joint4 (°)" and panda[3].low == pytest.approx(limits[3, 0], abs=0.01)
    value, note = panda[3].joint_value(10.0)  # joint 4's upper limit is about -4 degrees
    assert value == pytest.approx(np.radians(panda[3].high)) and "outside" in note


def test_a_lock_past_its_limit_is_clamped_and_said(tiny_chain_checkpoint):
    with running_app(ikdp.load(tiny_chain_checkpoint), solve_now=False, animation_seconds=0.0) as app:
        app.panel.samples.value = 2
        settle(app)
        controls = app.constraint_controls
        controls.lock_values[3].value = 10.0  # past panda_joint4's upper limit (a script may set it; the page cannot)
        controls.lock_boxes[3].value = True
        settle(app)
        assert np.allclose(app.solved.final_angles[:, 3], np.radians(controls.fields[3].high), atol=1e-6)
        assert "outside" in controls.readout.content


def test_best_is_a_sample_that_meets_the_constraints_and_none_meeting_is_explained(app):
    """Once "best" highlighted a sample through the obstacle while others cleared it, and 0 of 16
    met with no hint why."""
    from ikdp_viz.frame import best_sample

    controls = app.constraint_controls
    controls.add_obstacle(position=(0.9, 0.6, 0.0), radius=0.5)
    settle(app)
    final = holds(app.solved.state_violation[-1])
    assert final.any() and not final.all(), final  # this case has both kinds
    assert final[app.highlight_index()] and app.highlight_index() == best_sample(app.solved)
    assert "the best of the" in app.panel.readout_text.content  # "... meeting the constraints"
    controls.clear_obstacles()
    controls.add_obstacle(position=(0.0, 0.0, 0.0), radius=0.9)  # over the base: every link touches it
    settle(app)
    assert not holds(app.solved.state_violation[-1]).any()
    assert "no sample meets the constraints" in controls.readout.content and "obstacle" in controls.readout.content


def test_a_lock_that_keeps_the_hand_from_the_target_says_so():
    """A lock that made the target unreachable gave no message."""
    from viz_helpers import shipped_solver_or_skip

    with running_app(shipped_solver_or_skip("ikdp_n4"), target=(3.0, 0.0), animation_seconds=0.0) as app:
        settle(app)
        controls = app.constraint_controls
        assert "no sample reaches" not in controls.readout.content
        controls.lock_values[0].value = 180.0  # the first link points away: the tip reaches x = 2 at most
        controls.lock_boxes[0].value = True
        settle(app)
        assert app.solved.view.final_error.min() > 0.5
        assert "no sample reaches the target with these locks" in controls.readout.content


def test_turning_follow_off_gives_the_highlight_back_to_best(app):
    """Follow mode left the highlight on a sample number after it was turned off."""
    controls = app.constraint_controls
    controls.follow.value = True
    settle(app)
    drag_gizmo(app, 1.2, 1.0, phase="update")
    settle(app)
    assert app.panel.highlight.value != "best" and "kept by follow mode" in app.panel.readout_text.content
    controls.follow.value = False
    settle(app)
    assert app.panel.highlight.value == "best" and "kept by follow mode" not in app.panel.readout_text.content


def test_a_robot_s_dropped_obstacle_stands_clear_of_the_robot_shown_toward_the_camera(tiny_chain_checkpoint):
    """In 3-D the dropped sphere sat on the middle joint of the robot shown, inside its
    opaque meshes, and could not be seen. It now stands in front of it: clear of every link, toward the camera."""
    from ikdp_viz.camera import camera_fit_3d
    from ikdp_viz.constraint_scene import LINK_CLEARANCE, segment_distances

    with running_app(ikdp.load(tiny_chain_checkpoint), animation_seconds=0.0) as app:
        settle(app)
        controls, arm = app.constraint_controls, app.solver.arm
        points = arm.forward_kinematics(torch.as_tensor(controls.last_pose, dtype=torch.float64)[None])[0].numpy()
        controls.add_obstacle()
        settle(app)
        entry = controls.obstacles[0]
        reach = float(arm.reach[1])
        assert segment_distances(entry["position"], points).min() >= entry["radius"] + LINK_CLEARANCE * reach - 1e-9
        camera = camera_fit_3d(arm.reach_center.double().numpy(), reach)[0]
        middle = points[len(points) // 2]
        assert np.linalg.norm(camera - entry["position"]) < np.linalg.norm(camera - middle)  # in front of it
        assert np.allclose(entry["nodes"][1].position, entry["position"])  # its gizmo, and the sphere with it


def test_a_robot_s_obstacle_has_a_colour_of_its_own_and_a_legend_entry_while_drawn(tiny_chain_checkpoint):
    """An obstacle dragged onto the arm vanished among the failing robots drawn in the same red: its colour stands
    apart from every shade of "fails", and the legend names it while it is drawn, and only then."""
    with running_app(ikdp.load(tiny_chain_checkpoint), animation_seconds=0.0) as app:
        settle(app)
        controls = app.constraint_controls
        assert not any("obstacle" in entry.text for entry in app.writer.frame.legend)
        controls.add_obstacle()
        settle(app)
        color = np.array(controls.obstacles[0]["nodes"][0].color, dtype=float)
        for red in (VIOLATES, VIOLATES_OTHERS, VIOLATES_FAINT):
            assert np.linalg.norm(color - np.array(red)) > 100, (color, red)
        named = [entry for entry in app.writer.frame.legend if "obstacle" in entry.text]
        assert len(named) == 1 and np.allclose(named[0].swatch.color, color)
        assert "obstacle" in app.panel.learn.legend.content
        controls.clear_obstacles()
        settle(app)
        assert not any("obstacle" in entry.text for entry in app.writer.frame.legend)


def test_a_robot_with_no_sample_meeting_the_constraints_says_why_in_the_main_readout():
    """The Z1 read "Constraints hold for 0 of 16" with no hint why (the Constraints folder,
    closed by default, had one line). Both readouts now name the failing constraint and what to do."""
    from viz_helpers import shipped_solver_or_skip

    with running_app(shipped_solver_or_skip("ikdp_z1"), animation_seconds=0.0) as app:
        settle(app)
        controls, arm = app.constraint_controls, app.solver.arm
        points = arm.forward_kinematics(torch.as_tensor(controls.last_pose, dtype=torch.float64)[None])[0].numpy()
        controls.add_obstacle(position=points[len(points) // 2], radius=0.08)  # on the middle joint, as it was
        settle(app)
        assert not holds(app.solved.state_violation[-1]).any()
        readout = app.panel.readout_text.content
        assert "**Constraints hold** for 0 of" in readout
        assert "**no sample meets the constraints**: every sample touches an obstacle" in readout
        assert "**no sample meets the constraints**: every sample touches an obstacle" in controls.readout.content
        names = [name for name, _ in app.solved.final_violations]
        assert names == ["obstacles"] and not holds(app.solved.final_violations[0][1]).any()
        controls.clear_obstacles()
        controls.lock_values[1].value = 60.0
        controls.lock_boxes[1].value = True  # the shoulder held up: the hand cannot come down to the target
        settle(app)
        assert app.solved.view.final_error.min() > 0.05
        assert "**no sample reaches the target with these locks**" in app.panel.readout_text.content


def test_follow_mode_is_trackings_step_small_drags_reach_each_target_with_small_joint_steps():
    """Ten drags of 0.1 along a line on ikdp_n4: follow mode keeps what solver.track keeps on the same path from the
    same pose (every target reached within the arm's tolerance, the joints moving a little each step), and says no
    pull missed."""
    from viz_helpers import shipped_solver_or_skip

    solver = shipped_solver_or_skip("ikdp_n4")
    with running_app(solver, target=(2.2, 1.2), animation_seconds=0.0) as app:
        settle(app)
        controls = app.constraint_controls
        controls.follow.value = True
        settle(app)
        start = controls.last_pose.copy()
        path = np.array([[2.2 - 0.1 * step, 1.2] for step in range(1, 11)])
        request = app.solved.request
        tracked = solver.track(
            torch.as_tensor(path), torch.as_tensor(start), num_samples=request.num_samples,
            sampler=request.sampler, steps=request.steps, refine_steps=request.refine_steps,
            generator=torch.Generator().manual_seed(0),
        )  # fmt: skip
        assert bool(tracked.reached.all()) and tracked.largest_jump < 0.15  # what the library does here
        for index, (x, y) in enumerate(path):
            drag_gizmo(app, x, y, phase="update")
            settle(app)
            kept = controls.last_pose
            tip = solver.arm.end_effector(torch.as_tensor(kept, dtype=torch.float64)).numpy()
            assert np.linalg.norm(tip - (x, y)) < solver.arm.position_tolerance, (x, tip)
            np.testing.assert_allclose(kept, tracked.angles[index].numpy(), atol=1e-3)  # the pose track keeps
            text = controls.readout.content
            assert "missed" not in text and "branch switch" not in text, text
        assert controls.branch_switches == 0 and controls.largest_jump < 0.15


def test_the_overlay_draws_the_highlighted_sample_and_follows_the_highlight(app):
    from ikdp_viz.arm_kinds import arm_kind

    controls = app.constraint_controls
    controls.add_obstacle(position=(0.9, 0.6, 0.0), radius=0.5)
    settle(app)
    for choice in ("2", "5"):
        app.panel.highlight.value = choice  # drawn with the frame that shows that sample, never a stale one
        settle(app)
        sample = int(choice) - 1
        path, polylines = arm_kind(app.solver).sample_path(app.solved.view, sample)
        segments, _ = overlay_segments(path, app.solved.state_violation[:, sample], polylines)
        np.testing.assert_allclose(controls.overlay.points, segments, rtol=1e-5, atol=1e-6)
