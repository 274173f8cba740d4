"""The 3-D viewer's drawable arrays (chain_scene, robot_meshes, chain_readouts, arm_kinds): plain numpy, no viser."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
import torch
import trimesh

import ikdp
from ikdp.robots import load_robot, spatial_arm
from ikdp_viz.arm_kinds import ChainKind, arm_kind
from ikdp_viz.chain_scene import (
    build_chain_view,
    ghost_colors,
    gizmo_pose,
    hand_paths,
    initial_pose_target,
    mesh_poses,
    pose_target,
    skeleton_segments,
)
from ikdp_viz.readouts import chain_model_text, chain_solve_text, error_pair, pose_text
from ikdp_viz.robot_meshes import convex_hull, light_mesh, robot_meshes

K = 3  # samples per solve: enough to have a best one


@pytest.fixture(scope="module")
def solver(tiny_chain_checkpoint):
    return ikdp.load(tiny_chain_checkpoint)


@pytest.fixture(scope="module")
def view(solver):
    target = initial_pose_target(solver.arm)
    result = solver.solve(
        target[None], num_samples=K, return_trajectory=True, return_estimates=True,
        generator=torch.Generator().manual_seed(0),
    )  # fmt: skip
    return build_chain_view(result, solver.arm, target, ChainKind())


def test_the_view_holds_every_state_of_every_sample(view, solver):
    steps, joints = solver.timesteps, solver.arm.num_joints
    assert view.joint_values.shape == (steps + 1, K, joints)
    assert view.points.shape == (steps + 1, K, joints + 1, 3)
    assert view.position_error.shape == view.rotation_error.shape == (steps + 1, K)
    assert view.final_points.shape == (K, joints + 1, 3)
    assert view.estimate_points.shape == (steps, K, joints + 1, 3)
    assert view.labels[0] == steps and view.labels[-1] == 0
    assert view.tip_error is view.position_error  # the shared plot reads tip_error
    assert not view.refined
    np.testing.assert_array_equal(view.pose_at(view.num_states - 1, 1), view.final_joint_values[1])


def test_skeleton_segments_run_from_the_first_joint_to_the_hand_as_the_arm_computes(view, solver):
    arm = solver.arm
    segments = skeleton_segments(view.points)  # (S+1 * K * J, 2, 3)
    assert segments.shape == (view.num_states * K * arm.num_joints, 2, 3)
    per_sample = segments.reshape(view.num_states, K, arm.num_joints, 2, 3)
    fk = arm.forward_kinematics(torch.as_tensor(view.joint_values)).numpy()  # (S+1, K, J+1, 3)
    hand = arm.end_effector_frame(torch.as_tensor(view.joint_values))[1].numpy()  # (S+1, K, 3)
    np.testing.assert_allclose(per_sample[..., 0, 0, :], fk[..., 0, :], atol=1e-6)
    np.testing.assert_allclose(per_sample[..., -1, 1, :], hand, atol=1e-6)
    np.testing.assert_array_equal(per_sample[..., 1:, 0, :], per_sample[..., :-1, 1, :])  # a connected polyline
    np.testing.assert_array_equal(skeleton_segments(view.points[2]), per_sample[2].reshape(-1, 2, 3))


def test_the_trail_is_each_hand_moving_from_state_to_state(view):
    paths = hand_paths(view.points)  # (S+1, K, 2, 3)
    assert paths.shape == (view.num_states, K, 2, 3) and paths.dtype == np.float32
    np.testing.assert_allclose(paths[:, :, 1], view.points[:, :, -1], atol=1e-6)
    np.testing.assert_allclose(paths[1:, :, 0], view.points[:-1, :, -1], atol=1e-6)
    np.testing.assert_array_equal(paths[0, :, 0], paths[0, :, 1])  # pure noise: no step yet


def test_ghost_colors_fade_from_faint_to_grey_with_the_highlighted_sample_in_the_accent():
    colors = ghost_colors(5, 3, highlight=1)
    assert colors.shape == (5, 3, 3) and colors.dtype == np.uint8
    assert tuple(colors[0, 0]) == (238, 238, 238) and tuple(colors[-1, 2]) == (120, 120, 120)
    assert tuple(colors[-1, 1]) == (20, 90, 210)
    assert (np.diff(colors[:, 0].astype(int), axis=0) <= 0).all()


def test_the_hand_frame_is_the_forward_kinematics_of_the_best_sample(view, solver):
    best = view.best_sample()
    assert best == int(np.argmin(view.final_position_error + 0.1 * view.final_rotation_error))
    position, wxyz = gizmo_pose(solver.arm, view.final_joint_values[best])
    pose = solver.arm.end_effector_pose(torch.as_tensor(view.final_joint_values[best])).numpy()
    np.testing.assert_allclose(np.concatenate((position, wxyz)), pose, atol=1e-12)
    np.testing.assert_allclose(position, view.final_points[best, -1], atol=1e-6)
    goal = torch.as_tensor(view.target)
    expected = solver.arm.position_error(torch.as_tensor(view.final_joint_values[best]), goal)
    assert view.final_position_error[best] == pytest.approx(float(expected), abs=1e-6)


def test_the_first_target_is_the_hand_at_mid_limits():
    panda = load_robot("panda")
    target = initial_pose_target(panda)
    expected = panda.end_effector_pose(panda.joint_limits.double().mean(dim=-1)).numpy()
    np.testing.assert_allclose(target, expected, atol=1e-12)


def test_mesh_poses_place_each_mesh_on_its_link_for_a_batch_of_poses():
    panda = load_robot("panda")
    meshes = robot_meshes(panda)
    assert [mesh.name for mesh in meshes][:2] == ["panda_link0_0", "panda_link1_0"] and len(meshes) == 9
    assert all(mesh.vertices.shape[1] == 3 and mesh.faces.max() < len(mesh.vertices) for mesh in meshes)
    links = np.array([mesh.link_index for mesh in meshes])
    offsets = np.stack([mesh.offset for mesh in meshes])
    joints = panda.random_poses(4, generator=torch.Generator().manual_seed(1)).double().numpy()  # (4, J)
    positions, wxyzs = mesh_poses(panda, joints, links, offsets)
    assert positions.shape == (4, 9, 3) and wxyzs.shape == (4, 9, 4)
    frames = panda.link_poses(torch.as_tensor(joints)).numpy()[:, links] @ offsets  # (4, 9, 4, 4)
    np.testing.assert_allclose(positions, frames[..., :3, 3], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(wxyzs, axis=-1), 1.0, atol=1e-12)
    one_position, _ = mesh_poses(panda, joints[2], links, offsets)  # one pose: (M, 3)
    np.testing.assert_allclose(one_position, positions[2], atol=1e-12)


def test_a_ghosts_light_mesh_is_a_small_hull_inside_the_link_mesh_and_as_large():
    meshes = robot_meshes(load_robot("panda"))
    for mesh in meshes:
        vertices, faces = light_mesh(mesh.vertices, points=24)
        assert vertices.dtype == np.float32 and faces.dtype == np.int32 and faces.max() < len(vertices)
        assert len(faces) <= 2 * 24 - 4 < len(mesh.faces)  # 44 faces against the collision mesh's 200 to 300
        hull = trimesh.Trimesh(vertices, faces)
        assert hull.is_watertight and hull.volume > 0
        gaps = np.linalg.norm(vertices[:, None] - mesh.vertices[None], axis=-1).min(axis=1)
        assert gaps.max() < 1e-6  # its corners are the mesh's own vertices: inside the link, never beyond
        original = trimesh.Trimesh(mesh.vertices, mesh.faces).convex_hull
        assert hull.volume > 0.6 * original.volume  # the spread points keep most of the link's bulk
    few = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    vertices, faces = light_mesh(few, points=24)  # fewer vertices than points: their own hull
    assert len(vertices) == 4 and len(faces) == 4


def test_the_own_hull_is_scipys_hull_and_the_ghosts_need_no_scipy(monkeypatch):
    rng = np.random.default_rng(0)
    clouds = [rng.normal(size=(int(rng.integers(4, 40)), 3)) for _ in range(40)]
    clouds += [np.round(rng.normal(size=(30, 3))) for _ in range(20)]  # repeated and coplanar points
    clouds += [trimesh.creation.box().vertices, np.vstack([trimesh.creation.box().vertices] * 2)]
    for points in clouds:
        faces = convex_hull(points)
        hull = trimesh.Trimesh(points, faces)
        assert hull.is_watertight and hull.is_winding_consistent and hull.volume > 0  # outward, closed
        assert hull.volume == pytest.approx(trimesh.convex.convex_hull(points).volume, rel=1e-9)  # scipy's qhull
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0]])
    assert sorted(np.unique(convex_hull(square))) == [0, 1, 2, 3] and len(convex_hull(square)) == 4  # both sides
    assert len(convex_hull(np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2.0]]))) == 0  # a line has no faces
    monkeypatch.setitem(sys.modules, "scipy", None)  # no user extra installs scipy: the light meshes must not need it
    monkeypatch.setitem(sys.modules, "scipy.spatial", None)
    for mesh in robot_meshes(load_robot("panda")):
        vertices, faces = light_mesh(mesh.vertices)
        assert trimesh.Trimesh(vertices, faces).is_watertight


def test_the_saved_metrics_are_words_with_units_not_keys():
    metrics = {"eval_targets": 200, "tip_error_median": 0.0112, "tip_error_mean": 0.032, "tip_error_p95": 0.139,
               "sampler": "ddpm raw, K=1", "rotation_error_median": 0.0416, "rotation_error_mean": 0.2396,
               "limit_violations": 0, "step": 10000}  # fmt: skip
    text = chain_model_text(load_robot("panda"), 100, {"metrics": metrics})
    assert "**at save** (10,000 training steps, 200 targets, ddpm raw, K=1): " in text
    assert "hand position error median 11.2 mm, mean 32.0 mm, 95th percentile 139.0 mm" in text
    assert "rotation error median 2.4°, mean 13.7°; 0 joint-limit violations" in text
    assert "_" not in text.split("**at save**")[1]  # no raw key
    position_only = chain_model_text(load_robot("panda"), 100, {"metrics": {"tip_error_median": 0.002}})
    assert position_only.endswith("**at save**: hand position error median 2.0 mm")


def test_the_model_text_says_when_the_robots_meshes_are_not_here():
    panda = load_robot("panda")
    assert "No meshes" not in chain_model_text(panda, 100, {})
    elsewhere = ikdp.ChainArm.from_config({**panda.to_config(), "urdf_path": "/gone/panda.urdf"})
    text = chain_model_text(elsewhere, 100, {})
    assert "**No meshes**" in text and "panda.urdf" in text and "example-robot-data" in text
    assert "/gone" not in text  # never a path of the machine the model was trained on


def test_an_arm_without_meshes_draws_none_and_a_bad_choice_is_refused():
    assert robot_meshes(spatial_arm(2)) == []
    with pytest.raises(ValueError, match="prefer"):
        robot_meshes(load_robot("panda"), prefer="shiny")


def test_pose_targets_are_normalised_and_bad_ones_refused():
    np.testing.assert_allclose(pose_target((1, 2, 3), (0, 0, 0, -2)), [1, 2, 3, 0, 0, 0, -1])  # w = 0 kept
    np.testing.assert_allclose(pose_target((0, 0, 0), (-1, 0, -1, 0)), [0, 0, 0, 0.5**0.5, 0, 0.5**0.5, 0])
    with pytest.raises(ValueError, match="wxyz"):
        pose_target((0, 0, 0), (0, 0, 0, 0))
    with pytest.raises(ValueError, match="position"):
        pose_target((0, 0), (1, 0, 0, 0))


def test_the_chain_kind_pulls_a_far_target_onto_the_reach_ball(solver):
    kind = arm_kind(solver)
    assert isinstance(kind, ChainKind)
    center, reach = solver.arm.reach_center.double().numpy(), solver.arm.reach[1]
    inside = initial_pose_target(solver.arm)
    same, clamped = kind.clamp(solver, inside)
    np.testing.assert_allclose(same, inside, atol=1e-7)
    assert not clamped
    far, clamped = kind.clamp(solver, np.concatenate((center + (10.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0))))
    assert clamped and np.linalg.norm(far[:3] - center) == pytest.approx(reach, rel=1e-6)
    np.testing.assert_array_equal(far[3:], (0.0, 1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="point"):
        kind.clamp(solver, (1.0, 2.0))


def test_readouts_are_in_millimetres_and_degrees(view):
    assert error_pair(0.0123, math.pi / 2) == "12.3 mm / 90.00°"
    assert pose_text(np.array([0.1, -0.2, 0.3, 1.0, 0.0, 0.0, 0.0])).startswith(
        "**Target** x = +100.0, y = -200.0, z = +300.0 mm  \nwxyz = (1.000, +0.000"
    )
    text = chain_solve_text(view, 0, 1, sampler="ddpm", seed=3, refine_steps=0, solve_seconds=0.0125)
    now = error_pair(view.position_error[0, 1], view.rotation_error[0, 1])
    assert f"sample 2 of {K}" in text and f"{now} now" in text
    assert "**Solve** 12.5 ms (ddpm, 10 steps, seed 3)" in text and "refined" not in text
