"""TreeArm: a robot with several end effectors (a kinematic tree: a humanoid's two arms on one waist).

A tree is composed of serial chains (ikdp/chain_arm.py), one per end effector, each from the common base
link to its end effector. The pose is the vector of the J movable joints on those paths, each shared
joint once (the G1's waist serves both arms), in the order met walking the chains in the order the end
effectors were given. Each chain reads its own joints out of the pose, so a shared joint moves every
end effector above it, and forward kinematics is the chains' own (the shared joints' few products are
repeated per chain, which costs less than a second kinematics for trees).

Targets at the public boundary are (B, E, 7) poses or (B, E, 3) positions, one row per end effector in
the given order (`validate_targets`). Inside (the denoiser's condition, refinement, training) a target
is one flat row, every position first then every quaternion, (B, E * 7): the leading `position_dim`
= 3E entries are then the positions as for a chain, and the task error is the same stacking, every
position miss then every rotation miss (6E,), so damped least squares solves the stacked task of all
end effectors in one step and its clamp bounds the whole miss.

A tree's errors are the worst of its end effectors' (`tip_error`, `rotation_error`): a target is
reached when every end effector is within the tolerances; `errors_by_effector` gives each one's.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import torch

from ikdp.arm_inputs import drawing_device, validate_target_rows
from ikdp.chain_arm import QUATERNION_TOLERANCE, TARGET_KINDS, ChainArm
from ikdp.joint_limits import JointLimits
from ikdp.refine import RefinedByDampedLeastSquares
from ikdp.rotations import matrix_to_quaternion, quaternion_to_matrix
from ikdp.urdf import read_chain


class TreeArm(JointLimits, RefinedByDampedLeastSquares):
    """Several end effectors on one base: the movable joints of every base-to-end-effector path, each once."""

    kind = "tree"
    space_dim = 3  # a point in the arm's space (position_dim stacks the hands' positions)

    def __init__(self, chains: list[ChainArm], *, target: str = "pose"):
        """`chains`: one ChainArm per end effector, all from the same base link, shared joints named alike."""
        if target not in TARGET_KINDS:
            raise ValueError(f"target: expected one of {TARGET_KINDS}, got {target!r}")
        if len(chains) < 2:
            raise ValueError(f"chains: a tree has two or more end effectors, got {len(chains)}")
        bases = sorted({chain.base_link for chain in chains})
        if len(bases) != 1:
            raise ValueError(f"chains: expected one base link for every end effector, got {bases}")
        ee_links = [chain.ee_link for chain in chains]
        repeated = sorted({name for name in ee_links if ee_links.count(name) > 1})
        if repeated:
            raise ValueError(f"ee_links: each end effector once, got {repeated} more than once")
        for chain in chains:
            below = [other for other in ee_links if other != chain.ee_link and other in chain.link_names]
            if below:
                raise ValueError(
                    f"ee_links: {below[0]!r} is an ancestor of {chain.ee_link!r} (on its path from the base); "
                    f"give end effectors on different branches"
                )
        self.chains = [
            chain if chain.target == target else ChainArm.from_config({**chain.to_config(), "target": target})
            for chain in chains
        ]
        self.target = target
        self.base_link = bases[0]
        self.ee_links = ee_links
        names, types, limits, indices = [], [], [], []
        for chain in self.chains:
            for name, kind, limit in zip(chain.joint_names, chain.joint_types, chain._limits.tolist(), strict=True):
                if name not in names:
                    names.append(name)
                    types.append(kind)
                    limits.append(limit)
            indices.append([names.index(name) for name in chain.joint_names])
        self.joint_names, self.joint_types = names, types
        self._limits = torch.tensor(limits, dtype=torch.float64)  # (J, 2)
        self._continuous = torch.tensor([kind == "continuous" for kind in types])
        self._chain_indices = [torch.tensor(index) for index in indices]  # per chain, its joints in the tree's pose
        self.num_effectors = len(chains)
        self.per_effector_dim = 3 if target == "position" else 7
        self.target_dim = self.num_effectors * self.per_effector_dim  # one flat row: every position, then quaternions
        self.position_dim = 3 * self.num_effectors  # the leading target (and task error) entries that are positions
        self.condition_dim = self.num_effectors * (3 if target == "position" else 9)
        self._constants: dict = {}

    # --- construction --------------------------------------------------------------------------
    @classmethod
    def from_urdf(
        cls,
        urdf_path: str | Path,
        ee_links: list[str] | tuple[str, ...],
        *,
        target: str = "pose",
        base_link: str | None = None,
        package_dirs=(),
    ) -> TreeArm:
        """Read every base-to-end-effector chain of a URDF; the base defaults to the root of the first's tree."""
        ee_links = list(ee_links)
        if len(ee_links) < 2:
            raise ValueError(f"ee_links: a tree has two or more end effectors, got {ee_links}")
        first = read_chain(urdf_path, ee_links[0], base_link=base_link, package_dirs=package_dirs)
        chains = [first] + [
            read_chain(urdf_path, name, base_link=first.base_link, package_dirs=package_dirs) for name in ee_links[1:]
        ]
        return cls([ChainArm.from_description(chain, target=target) for chain in chains], target=target)

    def to_config(self) -> dict:
        """Plain values only: each chain's config (the URDF need not exist to rebuild the tree)."""
        return {
            "kind": self.kind,
            "chains": [chain.to_config() for chain in self.chains],
            "target": self.target,
            "joint_names": list(self.joint_names),  # what listings show; rebuilt from the chains
            "ee_links": list(self.ee_links),
        }

    @classmethod
    def from_config(cls, config: dict) -> TreeArm:
        if config.get("kind") != cls.kind:
            raise ValueError(f"config: expected kind 'tree', got {config.get('kind')!r}")
        return cls([ChainArm.from_config(chain) for chain in config["chains"]], target=config["target"])

    def __repr__(self) -> str:
        return f"TreeArm({self.base_link!r} -> {self.ee_links}, {self.num_joints} joints, target={self.target!r})"

    def __eq__(self, other) -> bool:
        return isinstance(other, TreeArm) and other.to_config() == self.to_config()

    def __hash__(self) -> int:
        return hash(("tree", tuple(self.joint_names), tuple(self.ee_links), self.target))

    # --- description ---------------------------------------------------------------------------
    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    num_links = num_joints

    @property
    def joint_limits(self) -> torch.Tensor:
        """(J, 2) lower, upper; continuous joints report (-pi, pi) and wrap instead of clamping."""
        return self._limits.float()

    @property
    def continuous_joints(self) -> torch.Tensor:
        return self._continuous.clone()

    @functools.cached_property
    def reach(self) -> tuple[float, float]:
        """(0, the largest of the chains' outer radii): each end effector has its own ball (`is_reachable`)."""
        return 0.0, max(chain.reach[1] for chain in self.chains)

    @functools.cached_property
    def span(self) -> float:
        """A length scale: the longest chain's span."""
        return max(chain.span for chain in self.chains)

    position_tolerance = ChainArm.position_tolerance
    rotation_tolerance = ChainArm.rotation_tolerance

    @functools.cached_property
    def link_names(self) -> list[str]:
        """Every link on a chain, each once: the first chain's, then each next chain's links not seen."""
        names = []
        for chain in self.chains:
            names += [name for name in chain.link_names if name not in names]
        return names

    # --- the chains' joints and targets -----------------------------------------------------------
    def _constants_like(self, like: torch.Tensor) -> dict:
        key = (like.dtype, like.device)
        if key not in self._constants:
            with torch.inference_mode(False):  # usable by autograd later, as the chain's constants
                eye = torch.eye(self.num_joints, dtype=like.dtype, device=like.device)
                self._constants[key] = {
                    "indices": [index.to(like.device) for index in self._chain_indices],
                    # (J_e, J): a chain's Jacobian columns placed among the tree's joints by one product
                    "placements": [eye[index.to(like.device)] for index in self._chain_indices],
                    "limits": self._limits.to(device=like.device, dtype=like.dtype),
                    "continuous": self._continuous.to(like.device),
                }
        return self._constants[key]

    def _as_joints(self, joints) -> torch.Tensor:
        joints = torch.as_tensor(joints)
        if not joints.is_floating_point():
            joints = joints.float()
        if joints.ndim < 1 or joints.shape[-1] != self.num_joints:
            raise ValueError(f"joints: expected shape (..., {self.num_joints}), got {tuple(joints.shape)}")
        return joints

    def _chain_joints(self, joints: torch.Tensor) -> list[torch.Tensor]:
        """(..., J) -> each chain's own joints (..., J_e)."""
        return [joints.index_select(-1, index) for index in self._constants_like(joints)["indices"]]

    def effector_targets(self, targets: torch.Tensor) -> list[torch.Tensor]:
        """A flat target row (..., target_dim) -> each end effector's own (..., 3) or (..., 7), as a chain takes it."""
        count = self.num_effectors
        positions = targets[..., : 3 * count]
        if self.target == "position":
            return [positions[..., 3 * e : 3 * e + 3] for e in range(count)]
        quaternions = targets[..., 3 * count :]
        return [
            torch.cat((positions[..., 3 * e : 3 * e + 3], quaternions[..., 4 * e : 4 * e + 4]), -1)
            for e in range(count)
        ]

    def flat_targets(self, targets: torch.Tensor) -> torch.Tensor:
        """(..., E, 3 or 7) one row per end effector -> the flat row (..., target_dim): positions, then quaternions."""
        positions = targets[..., :3].flatten(-2)
        if self.target == "position":
            return positions
        return torch.cat((positions, targets[..., 3:].flatten(-2)), dim=-1)

    def stacked_targets(self, targets: torch.Tensor) -> torch.Tensor:
        """The flat row (..., target_dim) -> (..., E, 3 or 7), one row per end effector (flat_targets' inverse)."""
        return torch.stack(self.effector_targets(targets), dim=-2)

    # --- kinematics ----------------------------------------------------------------------------
    def end_effector_frame(self, joints) -> tuple[torch.Tensor, torch.Tensor]:
        """(..., J) -> every end effector's rotation (..., E, 3, 3) and position (..., E, 3) in the base frame."""
        frames = [
            chain.end_effector_frame(part)
            for chain, part in zip(self.chains, self._chain_joints(self._as_joints(joints)), strict=True)
        ]
        return torch.stack([rotation for rotation, _ in frames], -3), torch.stack(
            [position for _, position in frames], -2
        )

    def end_effector_pose(self, joints) -> torch.Tensor:
        """(..., J) -> (..., E, 7): each end effector's position then unit quaternion (w, x, y, z)."""
        rotation, position = self.end_effector_frame(joints)
        return torch.cat([position, matrix_to_quaternion(rotation)], dim=-1)

    def end_effector(self, joints) -> torch.Tensor:
        """(..., J) -> the flat target row these joints reach, (..., target_dim)."""
        if self.target == "position":
            return self.end_effector_frame(joints)[1].flatten(-2)
        return self.flat_targets(self.end_effector_pose(joints))

    def forward_kinematics(self, joints) -> torch.Tensor:
        """(..., J) -> each chain's points (its joints' origins, then its end effector) one chain after another."""
        parts = self._chain_joints(self._as_joints(joints))
        return torch.cat([chain.forward_kinematics(part) for chain, part in zip(self.chains, parts, strict=True)], -2)

    def link_poses(self, joints) -> torch.Tensor:
        """(..., J) -> every link of `link_names` as a 4x4 in the base frame, (..., L, 4, 4)."""
        return self.link_poses_and_joint_axes(joints)[0]

    def link_poses_and_joint_axes(self, joints) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """`link_poses`, and every joint's world axis (..., J, 3) and origin (..., J, 3) after its motion, from one
        kinematics pass per chain: a self-collision check's depth and gradient read both."""
        joints = self._as_joints(joints)
        poses, seen = [], set()
        axes = joints.new_zeros(*joints.shape, 3)
        origins = joints.new_zeros(*joints.shape, 3)
        for chain, part, index in zip(
            self.chains, self._chain_joints(joints), self._constants_like(joints)["indices"], strict=True
        ):
            mine, frames, chain_origins = chain.link_poses_and_joint_frames(part)
            keep = [number for number, name in enumerate(chain.link_names) if name not in seen]
            seen.update(chain.link_names)
            poses.append(mine[..., keep, :, :])
            axes[..., index, :] = frames[..., :, 2]  # a shared joint sits alike on every chain
            origins[..., index, :] = chain_origins
        return torch.cat(poses, dim=-3), axes, origins

    def task_error_and_jacobian(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The stacked task error (..., 6E) or (..., 3E) and its Jacobian (..., 6E or 3E, J): every position row,
        then every rotation row. A small step dq changes the error by -J dq."""
        joints = self._as_joints(joints)
        placements = self._constants_like(joints)["placements"]
        errors, jacobians = [], []
        for chain, part, goal, placement in zip(
            self.chains, self._chain_joints(joints), self.effector_targets(targets), placements, strict=True
        ):
            error, jacobian = chain.task_error_and_jacobian(part, goal)
            errors.append(error)
            jacobians.append(jacobian @ placement)  # (..., 6, J_e) -> (..., 6, J)
        return self._stack_rows(errors, -1), self._stack_rows(jacobians, -2)

    def _stack_rows(self, parts: list[torch.Tensor], dim: int) -> torch.Tensor:
        """Each end effector's (position rows, rotation rows) along `dim` -> every position's, then every rotation's."""
        positions = [part.narrow(dim, 0, 3) for part in parts]
        if self.target == "position":
            return torch.cat(positions, dim=dim)
        return torch.cat(positions + [part.narrow(dim, 3, 3) for part in parts], dim=dim)

    def task_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        """What damped least squares drives to zero: every position miss, then every rotation error, (..., 6E)."""
        joints = self._as_joints(joints)
        errors = [
            chain.task_error(part, goal)
            for chain, part, goal in zip(
                self.chains, self._chain_joints(joints), self.effector_targets(targets), strict=True
            )
        ]
        return self._stack_rows(errors, -1)

    def jacobian(self, joints) -> torch.Tensor:
        """(..., J) -> the stacked geometric Jacobian (..., 6E or 3E, J), rows as `task_error`'s."""
        joints = self._as_joints(joints)
        placements = self._constants_like(joints)["placements"]
        parts = self._chain_joints(joints)
        jacobians = [
            chain.jacobian(part) @ placement
            for chain, part, placement in zip(self.chains, parts, placements, strict=True)
        ]
        return self._stack_rows(jacobians, -2)

    def errors_by_effector(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Each end effector's position error (..., E), metres, and for poses its rotation error (..., E),
        radians; float64 kinematics, float32 results, as a chain's `tip_and_rotation_errors`."""
        joints = self._as_joints(joints)
        pairs = [
            chain.tip_and_rotation_errors(part, goal)
            for chain, part, goal in zip(
                self.chains, self._chain_joints(joints), self.effector_targets(targets), strict=True
            )
        ]
        position = torch.stack([position for position, _ in pairs], dim=-1)
        if self.target == "position":
            return position, None
        return position, torch.stack([rotation for _, rotation in pairs], dim=-1)

    def joints_moving(self, link_indices) -> torch.Tensor:
        """(S,) indices into `link_names` -> (S, J) True where the joint moves that link (it lies on the link's
        path from the base)."""
        moving = torch.zeros(len(link_indices), self.num_joints, dtype=torch.bool)
        for row, link in enumerate(link_indices):
            name = self.link_names[link]
            number = next(n for n, chain in enumerate(self.chains) if name in chain.link_names)
            chain = self.chains[number]
            last = chain.link_frames[chain.link_names.index(name)]  # -1: the base, moved by nothing
            moving[row, self._chain_indices[number][: last + 1]] = True
        return moving

    @functools.cached_property
    def links_can_meet(self) -> bool:
        """True where links of different branches can touch (ikdp/tree_spheres.py): the solve then keeps them apart
        by default. False where they cannot, or where the links' geometry cannot be read (no URDF, no meshes or no
        trimesh: nothing to check against)."""
        from ikdp.tree_spheres import meeting_pairs, tree_link_spheres

        try:
            spheres = tree_link_spheres(self)
        except ValueError:
            return False
        return len(meeting_pairs(self, spheres)) > 0

    def with_default_constraints(self, constraints) -> list:
        """The constraints a solve runs: those given, and SelfCollision() where the links can meet and none was
        given (`ikdp.SelfCollision(enabled=False)` turns it off)."""
        from ikdp.self_collision import with_self_collision

        return with_self_collision(self, constraints)

    def collision_spheres(self, held_joints=None):
        """The LinkSpheres obstacles meet: the chains' sphere covers merged onto the tree (ikdp/tree_spheres.py)."""
        from ikdp.tree_spheres import tree_link_spheres

        return tree_link_spheres(self, held_joints)

    def position_only_targets(self, constraint, targets) -> torch.Tensor:
        """`PositionOnly(effectors=...)`'s targets: per end effector, the parts that count (tree_partial_targets)."""
        from ikdp.tree_partial_targets import effector_parts, validate_tree_targets

        return validate_tree_targets(self, effector_parts(self, constraint.effectors, constraint.name), targets)

    def bind_position_only(self, constraint):
        """`PositionOnly.bind` on a tree: each end effector's parts as `effectors` says."""
        from ikdp.partial_targets import checked_weight
        from ikdp.tree_partial_targets import BoundEffectorParts, effector_parts

        parts = effector_parts(self, constraint.effectors, constraint.name)
        return BoundEffectorParts(self, parts, checked_weight(constraint.weight, constraint.name))

    def small_batch_kinematics(self) -> TreeArm:
        """The tree itself: its chains share joints, so a few poses take the general kinematics (a chain's fused
        counterpart, ikdp/fused_chain.py, covers one end effector)."""
        return self

    def tip_and_rotation_errors(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """The worst end effector's position error (...) and (poses) the worst rotation error (...)."""
        position, rotation = self.errors_by_effector(joints, targets)
        return position.amax(dim=-1), None if rotation is None else rotation.amax(dim=-1)

    def position_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        """The worst end effector's distance to its target position, (...), metres."""
        return self.tip_and_rotation_errors(joints, targets)[0]

    tip_error = position_error

    def rotation_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        """The worst end effector's geodesic rotation error, (...), radians."""
        if self.target != "pose":
            raise ValueError(f"targets: rotation_error needs pose targets, this tree's are {self.target!r}")
        return self.tip_and_rotation_errors(joints, targets)[1]

    def target_features(self, targets: torch.Tensor) -> torch.Tensor:
        """(..., target_dim) -> (..., condition_dim): every position / span, then each rotation's first two columns."""
        count = self.num_effectors
        positions = targets[..., : 3 * count] / self.span
        if self.target == "position":
            return positions
        rotations = quaternion_to_matrix(targets[..., 3 * count :].unflatten(-1, (count, 4)))  # (..., E, 3, 3)
        return torch.cat([positions, rotations[..., :, 0].flatten(-2), rotations[..., :, 1].flatten(-2)], dim=-1)

    # --- targets -------------------------------------------------------------------------------
    def validate_targets(self, targets) -> torch.Tensor:
        """(B, E, 7) poses or (B, E, 3) positions, end effectors in `ee_links`' order -> the flat float32 rows
        (B, target_dim), quaternions normalised; a quaternion off unit norm by more than QUATERNION_TOLERANCE
        is refused, naming its row and end effector. The flat rows themselves (B, target_dim), what
        `end_effector` gives and the solver passes on (a tracked path's targets), are read back the same way."""
        count, width = self.num_effectors, self.per_effector_dim
        expected = f"(B, {count}, {width}): one row per end effector {self.ee_links}"
        try:
            if not isinstance(targets, torch.Tensor):
                targets = np.asarray(targets, dtype=np.float32)
            tensor = torch.as_tensor(targets, dtype=torch.float32)
        except (TypeError, ValueError, RuntimeError) as error:
            raise ValueError(f"targets: expected numbers of shape {expected}, could not read them ({error})") from None
        if tensor.ndim == 2 and tensor.shape[1] == self.target_dim:
            tensor = self.stacked_targets(tensor)
        if tensor.ndim != 3 or tuple(tensor.shape[1:]) != (count, width) or tensor.shape[0] == 0:
            raise ValueError(f"targets: expected shape {expected} with B >= 1, got {tuple(tensor.shape)}")
        validate_target_rows(tensor.reshape(len(tensor), -1), count * width)  # finite numbers
        if self.target == "pose":
            norms = tensor[..., 3:].double().norm(dim=-1)  # (B, E)
            bad = torch.nonzero((norms - 1).abs() > QUATERNION_TOLERANCE)
            if len(bad):
                row, effector = int(bad[0, 0]), int(bad[0, 1])
                raise ValueError(
                    f"targets: row {row}, end effector {self.ee_links[effector]!r} has quaternion "
                    f"{tensor[row, effector, 3:].tolist()} of norm {float(norms[row, effector]):.6g}, expected a unit "
                    f"quaternion (w, x, y, z)"
                )
            tensor = torch.cat([tensor[..., :3], tensor[..., 3:] / norms[..., None].float()], dim=-1)
        return self.flat_targets(tensor)

    def is_reachable(self, targets: torch.Tensor) -> torch.Tensor:
        """(B, target_dim) -> (B,) False where some end effector's position is certainly out of its chain's reach."""
        parts = self.effector_targets(targets)
        return torch.stack([chain.is_reachable(part) for chain, part in zip(self.chains, parts, strict=True)]).all(0)

    def clamp_to_workspace(self, targets: torch.Tensor) -> torch.Tensor:
        """Each end effector's position pulled onto its chain's reach ball where outside it."""
        parts = self.effector_targets(targets)
        clamped = [chain.clamp_to_workspace(part) for chain, part in zip(self.chains, parts, strict=True)]
        return self.flat_targets(torch.stack(clamped, dim=-2))

    # --- poses ---------------------------------------------------------------------------------
    def random_poses(self, count: int, *, generator: torch.Generator | None = None) -> torch.Tensor:
        """`count` poses with every joint uniform within its limits, (count, J), float32."""
        if count < 0:
            raise ValueError(f"count: expected a number of poses >= 0, got {count}")
        unit = torch.rand((count, self.num_joints), generator=generator, device=drawing_device(generator))
        limits = self._constants_like(unit)["limits"]
        return limits[:, 0] + unit * (limits[:, 1] - limits[:, 0])

    def random_poses_like(self, like: torch.Tensor, *, generator: torch.Generator | None = None) -> torch.Tensor:
        limits = self._constants_like(like)["limits"]
        unit = torch.rand(like.shape, generator=generator, device=like.device, dtype=like.dtype)
        return limits[:, 0] + unit * (limits[:, 1] - limits[:, 0])
