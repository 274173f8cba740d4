"""A tree's sphere cover, the link pairs that can meet, the self-collision constraint (on by default, with an off
switch) and obstacles against every moving link of a tree, on a small tree with collision bodies."""

import pytest
import torch
from tree_helpers import BODIES_URDF, two_arms, untrained_solver

import ikdp
from ikdp.obstacles import depth_and_gradient
from ikdp.tree_arm import TreeArm
from ikdp.tree_spheres import tree_link_spheres

FOLDED = [0.0, -1.2, -1.5, 1.2, 1.5]  # both forearms swung inward: the hands through each other and the torso


@pytest.fixture
def bodies(tmp_path, monkeypatch) -> TreeArm:
    monkeypatch.setenv("IKDP_CACHE", str(tmp_path / "cache"))  # the fitted spheres are stored there
    urdf = tmp_path / "bodies.urdf"
    urdf.write_text(BODIES_URDF)
    return TreeArm.from_urdf(urdf, ["left_hand", "right_hand"], target="position")


def link_pairs(arm, bound) -> set[tuple[str, str]]:
    names, links = arm.link_names, bound.spheres.link_indices
    return {tuple(sorted((names[links[a]], names[links[b]]))) for a, b in bound.pairs.tolist()}


def test_links_on_different_branches_can_meet_but_not_a_shoulder_on_its_torso(bodies):
    bound = ikdp.SelfCollision().bind(bodies, 1, 1)
    spheres = tree_link_spheres(bodies)
    assert {bodies.link_names[index] for index in spheres.link_indices} == {
        "torso",
        "l1",
        "left_hand",
        "r1",
        "right_hand",
    }
    assert link_pairs(bodies, bound) == {
        ("left_hand", "right_hand"),
        ("l1", "r1"),
        ("l1", "right_hand"),
        ("left_hand", "r1"),
        ("left_hand", "torso"),
        ("right_hand", "torso"),
    }  # l1 and r1 sit on the torso (adjacent); links of one arm never pair
    assert bodies.links_can_meet and not two_arms().links_can_meet  # no bodies there: nothing to check
    violation = bound.violation(torch.tensor([[0.0] * 5, FOLDED]))
    assert float(violation[0]) == 0 and float(violation[1]) > 0.1


def test_the_overlap_gradient_is_autograds(bodies):
    bound = ikdp.SelfCollision().bind(bodies, 1, 1)
    joints = bodies.random_poses(64, generator=torch.Generator().manual_seed(0)).double()
    joints[0] = torch.tensor(FOLDED, dtype=torch.float64)
    depth, gradient = bound.penetration_and_gradient(joints, 0.01)
    reference_depth, reference = depth_and_gradient(lambda leaf: bound.penetration(leaf, 0.01), joints)
    assert int((depth > 0).sum()) > 10
    torch.testing.assert_close(depth, reference_depth, atol=1e-12, rtol=0)
    torch.testing.assert_close(gradient, reference, atol=1e-10, rtol=0)


def test_solve_keeps_the_branches_apart_by_default_and_can_be_told_not_to(bodies):
    """The right hand's position asked, the left free: two joints to spare, where refinement clears the overlap."""
    solver = untrained_solver(bodies)
    check = ikdp.SelfCollision().bind(bodies, 1, 1)
    poses = bodies.random_poses(400, generator=torch.Generator().manual_seed(1))
    apart = poses[check.violation(poses) == 0][:12]
    targets = bodies.stacked_targets(bodies.end_effector(apart))  # (B, E, 3) that a pose free of overlap reaches
    free_left = ikdp.PositionOnly(effectors={"left_hand": "free"})
    options = dict(num_samples=8, sampler="ddim", steps=4, refine_steps=20)
    on = solver.solve(targets, **options, generator=torch.Generator().manual_seed(0), constraints=[free_left])
    off = solver.solve(
        targets,
        **options,
        generator=torch.Generator().manual_seed(0),
        constraints=[free_left, ikdp.SelfCollision(enabled=False)],
    )
    measured = {
        name: check.violation(out.angles.reshape(-1, 5)).reshape(12, 8) for name, out in (("on", on), ("off", off))
    }
    torch.testing.assert_close(on.constraint_violation.float(), measured["on"])  # the check is on by default
    assert bool((off.constraint_violation == 0).all()) and bool((measured["off"] > 0).any())  # and off when told
    overlapping = {name: float((violation > 0).float().mean()) for name, violation in measured.items()}
    assert overlapping["on"] < overlapping["off"] / 2, overlapping
    reached = (on.tip_error < 1e-3) & (on.constraint_violation == 0)
    assert bool(reached.any(-1).all())  # every target: a pose apart with the right hand on it


def test_self_collision_guides_only_the_late_steps_it_is_given(bodies):
    """Guidance acts on the x̂0 of the steps at t < guided_share * T: before, the estimate is too blurred to clear."""
    late = ikdp.SelfCollision().bind(bodies, 1, 1)
    assert late.guides_at(0.2) and not late.guides_at(0.8)
    every = ikdp.SelfCollision(guided_share=1.0).bind(bodies, 1, 1)
    assert every.guides_at(0.99)
    assert not any(ikdp.SelfCollision(guided_share=0.0).bind(bodies, 1, 1).guides_at(f) for f in (0.0, 0.5))
    with pytest.raises(ValueError, match="guided_share expected in \\[0, 1\\], got 1.5"):
        ikdp.SelfCollision(guided_share=1.5).bind(bodies, 1, 1)


def test_obstacles_act_on_every_moving_link_of_a_tree(bodies):
    solver = untrained_solver(bodies)
    joints = torch.tensor([[0.0, 1.0, 0.0, -1.0, 0.0]])
    targets = bodies.stacked_targets(bodies.end_effector(joints))
    left_hand = bodies.link_poses(joints)[0, bodies.link_names.index("left_hand"), :3, 3]  # the left hand, in the way
    obstacle = ikdp.Obstacles(centers=[left_hand.tolist()], radii=[0.05])
    check = obstacle.bind(bodies, 1, 1)
    assert float(check.violation(joints)) > 0
    _, gradient = check.penetration_and_gradient(joints.double(), 0.0)
    _, reference = depth_and_gradient(lambda leaf: check.penetration(leaf, 0.0), joints.double())
    torch.testing.assert_close(gradient, reference)
    out = solver.solve(
        targets[:, 1:].expand(-1, 2, -1).clone(),
        num_samples=8,
        sampler="ddim",
        steps=4,
        refine_steps=20,
        constraints=[obstacle, ikdp.PositionOnly(effectors={"left_hand": "free"})],
    )
    assert bool((out.constraint_violation == 0).any())  # the right hand on its target, the left clear of the ball


def test_self_collision_is_refused_on_a_chain():
    with pytest.raises(ValueError, match="self_collision: keeps the branches of a tree apart"):
        ikdp.load("ikdp_z1").solve(
            torch.zeros(1, 7) + torch.tensor([0.3, 0, 0.3, 1, 0, 0, 0]), constraints=[ikdp.SelfCollision()]
        )


@pytest.mark.slow  # fits the G1's sphere cover from its meshes on a fresh cache (about 15 s)
def test_the_g1s_hands_can_meet_the_torso_and_each_other_but_not_the_shoulder_its_torso():
    from ikdp.robot_data import example_robot_data_file

    urdf = example_robot_data_file("g1_description/urdf/g1_29dof_rev_1_0.urdf")
    g1 = TreeArm.from_urdf(urdf, ["left_rubber_hand", "right_rubber_hand"], base_link="pelvis")
    bound = ikdp.SelfCollision().bind(g1, 1, 1)
    pairs = link_pairs(g1, bound)
    assert ("left_wrist_yaw_link", "right_wrist_yaw_link") in pairs  # the hands through each other
    assert ("left_elbow_link", "torso_link") in pairs and ("right_wrist_pitch_link", "torso_link") in pairs
    assert ("left_shoulder_pitch_link", "torso_link") not in pairs  # adjacent
    assert not any(a.startswith("left") and b.startswith("left") for a, b in pairs)  # one arm's links never pair
    rest = torch.zeros(1, g1.num_joints)
    assert float(bound.violation(rest)) == 0  # the zero pose is free of overlap by construction
