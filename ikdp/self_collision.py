"""Self-collision of a tree at sampling time: a hand through the torso, the two hands through each other.

    solver.solve(targets)                                             # on by default where the links can meet
    solver.solve(targets, constraints=[ikdp.SelfCollision(enabled=False)])   # off

The links are the sphere cover the obstacles use (ikdp/tree_spheres.py), and the pairs checked are
those that can meet (`meeting_pairs`: different branches, not adjacent, apart at the zero pose). The
depth by which two checked spheres overlap (plus a clearance) is summed, and acts as an obstacle's
does (ikdp/obstacles.py): guidance moves x̂0 by a Gauss-Newton step that clears it while the hands
stay still, refinement clears it second to the targets, and it is the constraint's violation.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import torch

from ikdp.constraint_base import BoundConstraint, Constraint
from ikdp.obstacles import clearing_step

DEFAULT_CLEARANCE = 0.005  # fraction of the tree's span guidance aims beyond contact (refinement: half)
# Guidance acts on the x̂0 of the steps at t < GUIDED_SHARE * T: before, x̂0 is too blurred for its overlaps to say
# where the pose will land. On the G1 (100 collision-free targets, K = 16 + 5 DLS) the last half kept the returned
# poses' overlap at 9.4 % against 9.1 % with every step, the same 99 % solved apart, in 0.75x the time.
GUIDED_SHARE = 0.5


@dataclass(frozen=True)
class SelfCollision(Constraint):
    """Links of a tree's different branches kept apart; a tree whose links can meet has it unless it is given
    with `enabled=False`."""

    enabled: bool = True  # False: no self-collision check, even where the links can meet
    clearance: float | None = None  # the gap guidance aims for; None: DEFAULT_CLEARANCE of the tree's span
    weight: float = 1.0  # per step, the share of the overlap removed from x̂0
    guided_share: float = GUIDED_SHARE  # guidance on the steps at t < guided_share * T (1: every step)
    held_joints: Mapping[str, float] | None = None  # joints off every chain (fingers), as ikdp.Obstacles takes them
    name: ClassVar[str] = "self_collision"

    def bind(self, arm, batch: int, num_samples: int) -> BoundSelfCollision:
        if arm.kind != "tree":
            raise ValueError(f"self_collision: keeps the branches of a tree apart; {arm!r} has one chain")
        if not 0 <= self.weight <= 1:
            raise ValueError(f"self_collision: weight expected in [0, 1], got {self.weight}")
        if not 0 <= self.guided_share <= 1:
            raise ValueError(f"self_collision: guided_share expected in [0, 1], got {self.guided_share}")
        if self.clearance is not None and self.clearance < 0:
            raise ValueError(f"self_collision: clearance expected >= 0 metres, got {self.clearance}")
        from ikdp.tree_spheres import meeting_pairs, tree_link_spheres

        spheres = tree_link_spheres(arm, self.held_joints)
        clearance = DEFAULT_CLEARANCE * arm.span if self.clearance is None else float(self.clearance)
        return BoundSelfCollision(arm, spheres, meeting_pairs(arm, spheres), clearance, self.weight, self.guided_share)


def with_self_collision(arm, constraints) -> list[Constraint]:
    """A tree's constraints as a solve runs them: SelfCollision() added where its links can meet and none was
    given; one given with `enabled=False` taken out."""
    constraints = list(constraints)
    given = [item for item in constraints if isinstance(item, SelfCollision)]
    if not given and arm.links_can_meet:
        return [*constraints, SelfCollision()]
    return [item for item in constraints if not (isinstance(item, SelfCollision) and not item.enabled)]


@dataclass
class BoundSelfCollision(BoundConstraint):
    arm: object
    spheres: object  # LinkSpheres on the tree's links
    pairs: torch.Tensor  # (P, 2) the sphere pairs that can meet
    clearance: float
    weight: float
    guided_share: float = GUIDED_SHARE

    def __post_init__(self):
        # the pairs as a block: the spheres that come first in some pair against those that come second (27 x 68
        # on the G1's hands, of 76 x 76), so one batched distance product covers every pair
        self.first, first = self.pairs[:, 0].unique(return_inverse=True)
        self.second, second = self.pairs[:, 1].unique(return_inverse=True)
        self.checked = torch.zeros(len(self.first), len(self.second), dtype=torch.bool)  # (F, T) the pairs
        self.checked[first, second] = True
        self.moving = self.arm.joints_moving(self.spheres.link_indices)  # (S, J)
        self.revolute = torch.tensor([kind != "prismatic" for kind in self.arm.joint_types])
        self._like: dict = {}

    def _constants(self, like: torch.Tensor) -> dict:
        key = (like.dtype, like.device)
        if key not in self._like:
            radii = self.spheres.radii_like(like)
            first, second = self.first.to(like.device), self.second.to(like.device)
            reach = radii[first][:, None] + radii[second][None, :]  # (F, T) the distance at contact
            self._like[key] = {
                "first": first,
                "second": second,
                # a pair not checked never reaches: its overlap is zero without a mask to multiply by
                "reach": torch.where(self.checked.to(like.device), reach, torch.full_like(reach, -1e9)),
                "links": torch.tensor(self.spheres.link_indices, device=like.device),
                "centers": torch.tensor(self.spheres.centers, dtype=like.dtype, device=like.device),  # (S, 3)
                "moving": self.moving.to(device=like.device, dtype=like.dtype),
                "revolute": self.revolute.to(like.device),
            }
        return self._like[key]

    def _overlaps(self, centers: torch.Tensor, clearance: float) -> tuple[torch.Tensor, torch.Tensor]:
        """centers (M, S, 3) -> each checked pair's overlap (M, F, T), zero elsewhere, and the distances."""
        constants = self._constants(centers)
        # every pair's distance at once: one batched product, where gathering the P checked pairs cost 2x more
        distance = torch.cdist(centers[:, constants["first"]], centers[:, constants["second"]])
        return torch.relu(constants["reach"] + clearance - distance), distance

    def _world_centers(self, joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """joints (M, J) -> the sphere centres in the base frame (M, S, 3) (LinkSpheres.world_centers, its
        constants made once), and the joints' world axes and origins (M, J, 3) from the same kinematics pass."""
        constants = self._constants(joints)
        poses, axes, origins = self.arm.link_poses_and_joint_axes(joints)
        poses = poses[:, constants["links"]]  # (M, S, 4, 4)
        return (poses[..., :3, :3] @ constants["centers"][..., None])[..., 0] + poses[..., :3, 3], axes, origins

    def penetration(self, joints: torch.Tensor, clearance: float = 0.0) -> torch.Tensor:
        """joints (M, J) -> (M,) the summed overlap of the checked sphere pairs, + `clearance`."""
        return self._overlaps(self._world_centers(joints)[0], clearance)[0].sum(dim=(-1, -2))

    def penetration_and_gradient(self, joints: torch.Tensor, clearance: float) -> tuple[torch.Tensor, torch.Tensor]:
        """(M,) overlap and its gradient (M, J) in closed form, as a chain's obstacle depth (ikdp/obstacles.py).

        With g_s = dP/dc_s for sphere centre c_s (the unit vectors of its overlapping pairs, pushed apart), a
        revolute joint j that moves c_s turns it at a_j x (c_s - o_j), so dP/dq_j = a_j . (sum_s c_s x g_s -
        o_j x sum_s g_s), the sums over the spheres j moves; a prismatic one slides it: a_j . sum_s g_s.
        (Autograd through the pair distances took several times longer.)
        """
        centers, axes, origins = self._world_centers(joints)
        overlap, distance = self._overlaps(centers, clearance)
        return overlap.sum(dim=(-1, -2)), self._gradient(centers, axes, origins, overlap, distance)

    def _gradient(self, centers, axes, origins, overlap, distance) -> torch.Tensor:
        """`penetration_and_gradient`'s gradient (M, J) from its kinematics and overlaps."""
        constants = self._constants(centers)
        weights = torch.where(overlap > 0, distance.clamp_min(1e-12).reciprocal(), 0.0)  # (M, F, T)
        first, second = centers[:, constants["first"]], centers[:, constants["second"]]
        # g = -sum w (c_s - c_other) for each sphere of a pair, as products rather than (M, F, T, 3) differences
        per_sphere = torch.zeros_like(centers)
        per_sphere.index_add_(1, constants["first"], weights @ second - weights.sum(-1, keepdim=True) * first)
        turned_weights = weights.transpose(-1, -2)
        per_sphere.index_add_(
            1, constants["second"], turned_weights @ first - turned_weights.sum(-1, keepdim=True) * second
        )
        moving = constants["moving"]  # (S, J)
        pulled = torch.einsum("msk,sj->mjk", per_sphere, moving)  # (M, J, 3) sum_s g_s
        turned = torch.einsum("msk,sj->mjk", torch.linalg.cross(centers, per_sphere, dim=-1), moving)
        lever = torch.where(
            constants["revolute"][:, None], turned - torch.linalg.cross(origins, pulled, dim=-1), pulled
        )
        return (axes * lever).sum(dim=-1)

    def guides_at(self, fraction: float) -> bool:
        return fraction < self.guided_share

    def guide(self, joints):
        """The obstacles' clearing step (ikdp.obstacles.clearing_step), worked out only for the rows that overlap:
        a quarter to a half of a solve's x̂0, and the gradient costs more than finding them. One kinematics pass
        serves both."""
        centers, axes, origins = self._world_centers(joints)
        overlap, distance = self._overlaps(centers, self.clearance)
        depth = overlap.sum(dim=(-1, -2))
        rows = torch.nonzero(depth > 0)[:, 0]
        step = torch.zeros_like(joints)
        if len(rows):
            gradient = self._gradient(centers[rows], axes[rows], origins[rows], overlap[rows], distance[rows])
            step[rows] = clearing_step(self.arm, joints[rows], depth[rows], gradient, self.weight)
        return step

    def penetration_rows(self, joints):
        depth, gradient = self.penetration_and_gradient(joints, self.clearance / 2)
        return depth[:, None], gradient[:, None, :]

    def violation(self, joints):
        return self.penetration(joints)

    def of_rows(self, rows: torch.Tensor) -> BoundSelfCollision:
        return self  # the same pairs for every row
