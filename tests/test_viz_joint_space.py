"""The joint-space view: the exact 2-link solution set, angles on the torus, the denoiser's field, its drawing.

The maths and the arrays are checked as plain numpy (no viser); the last tests run the
app in-process and read the view's nodes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from viz_helpers import running_app, settle, shipped_solver_or_skip

import ikdp
from ikdp_viz.joint_space import (
    clean_estimates,
    clean_estimates_of_vectors,
    field_at,
    grid_poses,
    link_headings,
    model_timestep,
    shortest_difference,
    torus_grid,
    two_link_solutions,
    wrap_to_square,
)
from ikdp_viz.joint_space_view import (
    arrow_segments,
    cross_segments,
    curve_segments,
    square_beside,
)
from ikdp_viz.planar_scene import state_labels

TWO_LINK = "ikdp_n2"


@pytest.fixture(scope="module")
def two_link_solver():
    return shipped_solver_or_skip(TWO_LINK)


def tips(lengths, headings) -> np.ndarray:
    return ikdp.tip_position(torch.as_tensor(headings, dtype=torch.float64), list(lengths)).numpy()


# ------------------------------------------------------------------ the solution set


@pytest.mark.parametrize("lengths", [(1.0, 1.0), (1.0, 0.6), (0.7, 1.3)])
def test_every_analytic_solution_puts_the_tip_on_the_target(lengths):
    inner, outer = ikdp.arm.PlanarArm(lengths).reach
    generator = np.random.default_rng(0)
    for _ in range(50):
        radius = generator.uniform(inner + 1e-3, outer - 1e-3)
        angle = generator.uniform(-math.pi, math.pi)
        target = radius * np.array([math.cos(angle), math.sin(angle)])
        solutions = two_link_solutions(lengths, target)
        assert solutions.points.shape == (2, 2) and solutions.curve is None  # elbow up and elbow down
        assert np.abs(tips(lengths, solutions.points) - target).max() < 1e-9
        assert not np.allclose(solutions.points[0], solutions.points[1])


def test_a_target_on_the_reach_boundary_has_one_solution():
    outer = two_link_solutions((1.0, 0.6), (1.6 * math.cos(0.4), 1.6 * math.sin(0.4)))
    assert outer.points.shape == (1, 2) and outer.curve is None
    assert np.allclose(outer.points[0], [0.4, 0.4])  # stretched: both links along the target
    inner = two_link_solutions((1.0, 0.6), (0.0, -0.4))  # |l1 - l2| = 0.4: the inner boundary, folded
    assert inner.points.shape == (1, 2)
    assert np.abs(tips((1.0, 0.6), inner.points) - [0.0, -0.4]).max() < 1e-9
    assert np.isclose(abs(shortest_difference(inner.points[0, 0], inner.points[0, 1])), math.pi)


def test_the_base_of_an_arm_with_equal_links_is_a_curve_of_solutions():
    solutions = two_link_solutions((1.0, 1.0), (0.0, 0.0))
    assert solutions.points.shape == (0, 2)
    curve = solutions.curve
    assert curve.shape[0] >= 64 and np.abs(tips((1.0, 1.0), curve)).max() < 1e-9
    # in headings: theta2 = theta1 + pi (the elbow folded back, relative angle pi) for every theta1
    assert np.allclose(np.abs(shortest_difference(curve[:, 0], curve[:, 1])), math.pi)
    assert curve[:, 0].min() == -math.pi and curve[:, 0].max() > math.pi - 0.1  # all the way round


def test_a_target_out_of_reach_gives_the_solutions_of_the_nearest_reachable_point():
    solutions = two_link_solutions((1.0, 1.0), (0.0, 5.0))
    assert solutions.points.shape == (1, 2) and np.allclose(solutions.points[0], [math.pi / 2] * 2)


def test_lengths_other_than_two_links_are_refused():
    with pytest.raises(ValueError, match="lengths"):
        two_link_solutions((1.0, 1.0, 1.0), (0.5, 0.5))


# ------------------------------------------------------------------ the torus


def test_wrapping_puts_every_angle_in_minus_pi_to_pi_with_pi_on_the_left_edge():
    assert wrap_to_square(math.pi) == -math.pi and wrap_to_square(-math.pi) == -math.pi
    assert np.isclose(wrap_to_square(3 * math.pi + 0.5), -math.pi + 0.5)
    angles = wrap_to_square(np.linspace(-20, 20, 1001))
    assert angles.min() >= -math.pi and angles.max() < math.pi
    assert np.allclose(np.cos(angles), np.cos(np.linspace(-20, 20, 1001)))
    # the shortest way from 3 to -3 crosses the seam: +0.28, not -6
    assert np.isclose(shortest_difference(3.0, -3.0), 2 * math.pi - 6.0)
    assert np.isclose(shortest_difference(-3.0, 3.0), 6.0 - 2 * math.pi)


def test_the_grid_covers_the_torus_and_holds_the_other_joints():
    grid = torus_grid(4)
    assert grid.shape == (16, 2) and np.allclose(grid[:4, 0], [-0.75 * math.pi, -0.25 * math.pi, 0.25 * math.pi,
                                                                0.75 * math.pi])  # fmt: skip
    poses = grid_poses(grid, (1, 3), held=[0.1, 0.2, 0.3, 0.4])
    assert poses.shape == (16, 4) and np.all(poses[:, 0] == 0.1) and np.all(poses[:, 2] == 0.3)
    assert np.array_equal(poses[:, [1, 3]], grid)
    with pytest.raises(ValueError, match="joints"):
        grid_poses(grid, (2, 2), held=[0.0, 0.0, 0.0])


# ------------------------------------------------------------------ the field


def test_the_field_is_the_library_loops_x0_estimate_of_the_same_x_t(two_link_solver, monkeypatch):
    """Record every x_t the sampling loop gives the denoiser; our estimate of each equals the solve's x̂0."""
    # one numeric path: the loop's compiled step rounds in another order (4e-5 rad here on an AMD EPYC), and
    # its agreement with torch is tests/test_film_compiled.py's
    monkeypatch.setattr("ikdp.denoisers.film.compiled_workspace", lambda *args: None)
    solver, target = two_link_solver, (1.2, 0.5)
    denoiser, seen = solver.model.denoiser, []
    plain = denoiser.denoise

    def recording(x, *args, **kwargs):
        seen.append(x.clone())
        return plain(x, *args, **kwargs)

    monkeypatch.setattr(denoiser, "denoise", recording)
    out = solver.solve([target], num_samples=4, sampler="ddim", steps=5, return_estimates=True,
                       generator=torch.Generator().manual_seed(0))  # fmt: skip
    monkeypatch.undo()  # our estimates below call the denoiser itself, in torch
    assert len(seen) == len(out.timesteps) == 5
    for index, (x, t) in enumerate(zip(seen, out.timesteps, strict=True)):
        ours = clean_estimates_of_vectors(solver, x, t, target).double().numpy()  # (K, 2)
        library = out.estimates[index, 0].double().numpy()
        assert np.abs(shortest_difference(library, ours)).max() < 1e-5, f"step {index} (t = {t})"


def test_the_field_has_one_arrow_per_grid_pose(two_link_solver):
    field = field_at(two_link_solver, (1.2, 0.5), 40, (0, 1), held=[0.0, 0.0], count=12)
    assert field.starts.shape == field.arrows.shape == (144, 2) and field.timestep == 40
    assert field.arrows.min() >= -math.pi and field.arrows.max() < math.pi
    estimates = clean_estimates(two_link_solver, field.starts, 40, (1.2, 0.5))
    assert np.allclose(field.arrows, shortest_difference(field.starts, estimates))
    later = field_at(two_link_solver, (1.2, 0.5), 39, (0, 1), held=[0.0, 0.0], count=12)
    assert not np.allclose(later.arrows, field.arrows)  # another timestep, another field


def test_at_small_t_the_arrows_are_short_on_the_solutions_and_long_elsewhere(two_link_solver):
    target = (1.2, 0.5)
    solutions = two_link_solutions(two_link_solver.lengths, target).points
    for t in (0, 2):
        on_solutions = shortest_difference(solutions, clean_estimates(two_link_solver, solutions, t, target))
        assert np.linalg.norm(on_solutions, axis=-1).max() < 0.05, t
    field = field_at(two_link_solver, target, 0, (0, 1), held=[0.0, 0.0], count=16)
    assert np.median(np.linalg.norm(field.arrows, axis=-1)) > 0.5  # a typical pose is far from both


# ------------------------------------------------------------------ the drawing arrays


def test_the_square_maps_the_torus_beside_the_workspace():
    square = square_beside(2.0)
    (cx, cy), half = square.centre, square.side / 2
    assert cx - half > 2.0  # right of the outer circle
    corners = square.place(np.array([[-math.pi, -math.pi], [math.pi, 0.0]]))
    assert np.allclose(corners[0], [cx - half, cy - half, 0.0])
    assert np.allclose(corners[1], [cx - half, cy, 0.0])  # pi is -pi: the left edge


def test_a_curve_crossing_the_seam_is_cut_there_and_arrows_stay_within_a_cell():
    square = square_beside(2.0)
    curve = two_link_solutions((1.0, 1.0), (0.0, 0.0)).curve
    segments = curve_segments(square, curve, 0.0)
    lengths = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=-1)
    assert 0 < len(segments) < len(curve) and lengths.max() < 0.1 * square.side
    assert cross_segments(square, np.zeros((3, 2)), 0.0).shape == (6, 2, 3)
    count = 10
    starts = torus_grid(count)
    arrows = np.tile([math.pi - 1e-9, -math.pi], (len(starts), 1))  # the longest arrows there are
    drawn = arrow_segments(square, starts, arrows, count, 0.0)
    assert drawn.shape == (3 * count * count, 2, 3)
    shafts = drawn[0::3]
    cell = square.side / count
    assert np.linalg.norm(shafts[:, 1] - shafts[:, 0], axis=-1).max() <= cell * (1 + 1e-9)


def test_headings_come_back_from_joint_positions_and_states_map_to_the_denoisers_call():
    headings = np.array([[0.3, -2.0, 3.0]])
    joints = ikdp.forward_kinematics(torch.tensor(headings)).numpy()
    assert np.allclose(link_headings(joints), headings)
    labels = state_labels(list(range(79, -1, -1)))  # DDPM, T = 80: states at t = 80 .. 0
    assert model_timestep(labels, 0) == 79 and model_timestep(labels, 80) == 0 and model_timestep(labels, 79) == 0
    labels = state_labels([79, 53, 26, 0])  # DDIM, 4 steps
    assert [model_timestep(labels, state) for state in range(5)] == [79, 53, 26, 0, 0]


# ------------------------------------------------------------------ in the app


def test_toggling_the_view_draws_its_nodes_and_the_slider_moves_the_samples(two_link_solver):
    with running_app(two_link_solver, animation_seconds=0.0, target=(1.2, 0.5)) as app:
        settle(app)
        nodes, controls = app.writer.stage.joint_space, app.panel.joint_space
        assert not nodes.shown and controls.first.disabled  # off by default; N = 2 has no joints to choose
        controls.show.value = True
        assert nodes.shown
        count, num_samples = int(controls.grid.value), int(app.panel.samples.value)
        assert nodes.arrows.points.shape == (3 * count * count, 2, 3)
        assert nodes.samples.points.shape == (num_samples, 3)
        assert np.array_equal(nodes.samples.colors, app.writer.frame.palette.dots)  # the frame's own dot colours
        assert nodes.solutions.points.shape == (4, 2, 3)  # two crosses: elbow up and elbow down
        final_samples, final_arrows = nodes.samples.points.copy(), nodes.arrows.points.copy()
        assert nodes.last_field.timestep == 0
        app.panel.timestep.value = 40
        assert nodes.last_field.timestep == 39  # the denoiser's call on the state at t = 40
        assert not np.allclose(nodes.samples.points, final_samples)
        assert not np.allclose(nodes.arrows.points, final_arrows)
        app.panel.timestep.value = 70  # the dots must not be faint on the light square near t = T
        assert (nodes.samples.colors.min(axis=-1) <= 60).all()  # dark (or the deep blue) at every step, not FAINT
        app.move_target((0.0, 0.0))  # the base: a curve of solutions
        settle(app)
        assert len(nodes.solutions.points) > 64
        controls.show.value = False
        assert not nodes.shown and nodes.arrows is None


def test_for_more_links_two_chosen_joints_are_shown_against_the_final_samples(tiny_checkpoint):
    solver = ikdp.load(tiny_checkpoint)  # N = 3
    with running_app(solver, animation_seconds=0.0) as app:
        settle(app)
        nodes, controls = app.writer.stage.joint_space, app.panel.joint_space
        controls.show.value = True
        assert controls.first.options == ("θ1", "θ2", "θ3") and not controls.first.disabled
        controls.second.value = "θ3"
        assert controls.joints() == (0, 2)
        view = app.solved.view
        assert nodes.solutions.points.shape == (2 * view.num_samples, 2, 3)  # a cross on each final sample
        # the crosses stay inside the square, which stands clear of the ground grid; they are
        # not the target's red, the legend says what they are, and each axis ends in -π / π
        (cx, cy), half = nodes.square.centre, nodes.square.side / 2
        points = nodes.solutions.points
        assert (np.abs(points[..., 0] - cx) <= half + 1e-6).all() and (np.abs(points[..., 1] - cy) <= half + 1e-6).all()
        assert cx - half > app.writer.view.grid_half_width
        assert not (nodes.solutions.colors == (220, 25, 25)).all(axis=-1).any()
        assert "joint space: the final samples" in app.panel.learn.legend.content
        assert {label.text for label in nodes.labels} >= {"−π", "π"}
        app.panel.timestep.value = 5
        headings = link_headings(view.joints[app.state])
        field = nodes.last_field
        assert np.allclose(nodes.samples.points[:, :2], nodes.square.place(headings[:, [0, 2]])[:, :2], atol=1e-5)
        # the other joint is held at the highlighted sample's value: the field is that of those poses
        held = headings[app.highlight_index()]
        estimates = clean_estimates(solver, grid_poses(field.starts, (0, 2), held), field.timestep, view.target)
        assert np.allclose(field.arrows, shortest_difference(field.starts, estimates[:, [0, 2]]), atol=1e-6)
