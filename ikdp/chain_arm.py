"""ChainArm: a spatial serial chain (a URDF robot arm) behind PlanarArm's interface (ikdp/arm.py).

The pose is the vector of the J movable joints' values (radians, metres for prismatic joints),
in the order from the base. Fixed joints are folded into constant offsets, so forward kinematics
is a short product: for each joint, a constant offset (R_j, t_j) then the joint's motion, a
rotation about its axis (Rodrigues: I + sin q K + (1 - cos q) K^2, with the offset premultiplied
so each step is one batched 3x3 product) or a slide along it.

A target is a position (B, 3) or a pose (B, 7) = position in metres in the base link's frame
followed by a unit quaternion (w, x, y, z), chosen at construction (`target="position"` or
`"pose"`). The task error that damped least squares drives to zero is the position difference,
plus for poses the rotation error as an axis-angle vector log(R_target R_current^T) in the base
frame; `jacobian` is the matching geometric Jacobian (linear rows, then angular rows).

`to_config()` holds only numbers, strings and lists, so a checkpoint loaded with
`weights_only=True` rebuilds the arm without the URDF file. The path it records is the training
machine's; `urdf_path` answers with the file on this machine (`recorded_urdf_path` keeps the other).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import torch

from ikdp.arm_inputs import FEW_ROWS, drawing_device, few_rows_on_cpu, validate_target_rows
from ikdp.fused_chain import FusedChain
from ikdp.joint_limits import JointLimits
from ikdp.refine import RefinedByDampedLeastSquares
from ikdp.robot_data import installed_copy
from ikdp.rotations import (
    matrix_to_quaternion,
    origin_matrix,
    quaternion_angle,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_axis_angle,
    quaternion_to_matrix,
)
from ikdp.urdf import ChainDescription, read_chain

TARGET_KINDS = ("position", "pose")
QUATERNION_TOLERANCE = 1e-3  # how far from 1 a target quaternion's norm may be before it is refused


def axis_basis(axis: torch.Tensor) -> torch.Tensor:
    """A rotation (3, 3) whose third column is the unit `axis` (3,): z of the basis points along it."""
    helper = torch.zeros_like(axis)
    helper[int(axis.abs().argmin())] = 1.0  # the coordinate axis least parallel to `axis`
    first = torch.linalg.cross(helper, axis)
    first = first / first.norm()
    return torch.stack([first, torch.linalg.cross(axis, first), axis], dim=-1)


class ChainArm(JointLimits, RefinedByDampedLeastSquares):
    """A serial chain of revolute, continuous and prismatic joints; targets are positions or poses."""

    kind = "chain"
    position_dim = 3  # the leading target entries that are a position
    space_dim = 3  # a point in the arm's space

    def __init__(
        self,
        *,
        joint_names: list[str],
        joint_types: list[str],
        joint_offsets: list,
        joint_axes: list,
        joint_limits: list,
        ee_offset: list,
        link_names: list[str],
        link_frames: list[int],
        link_offsets: list,
        base_link: str,
        ee_link: str,
        urdf_path: str | None = None,
        target: str = "pose",
        description: ChainDescription | None = None,
    ):
        """Every argument is plain numbers so the arm rebuilds from `to_config()`; see `from_urdf`.

        joint_offsets (J, 4, 4): joint j's frame at zero in the frame of the joint before it (the base
        link for j = 0), fixed joints folded in; joint_axes (J, 3) unit axes in the joint frames;
        joint_limits (J, 2) lower, upper (continuous joints: -pi, pi); ee_offset (4, 4): the
        end-effector link in the last joint's frame; link_frames[i] the joint whose frame link i hangs
        from (-1: the base) and link_offsets[i] (4, 4) its offset there.
        """
        if target not in TARGET_KINDS:
            raise ValueError(f"target: expected one of {TARGET_KINDS}, got {target!r}")
        count = len(joint_names)
        if count < 1:
            raise ValueError("joint_names: expected one or more movable joints, got none")
        for name, value, shape in (
            ("joint_types", joint_types, (count,)),
            ("joint_offsets", joint_offsets, (count, 4, 4)),
            ("joint_axes", joint_axes, (count, 3)),
            ("joint_limits", joint_limits, (count, 2)),
            ("ee_offset", ee_offset, (4, 4)),
        ):
            got = (len(value),) if name == "joint_types" else tuple(torch.as_tensor(value).shape)
            if got != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {got}")
        unknown = sorted(set(joint_types) - {"revolute", "continuous", "prismatic"})
        if unknown:
            raise ValueError(f"joint_types: expected revolute, continuous or prismatic, got {unknown}")
        if len(link_names) != len(link_frames) or len(link_names) != len(link_offsets):
            raise ValueError(
                f"link_names, link_frames, link_offsets: expected equal lengths, got {len(link_names)}, "
                f"{len(link_frames)}, {len(link_offsets)}"
            )
        self.joint_names = [str(name) for name in joint_names]
        self.joint_types = [str(kind) for kind in joint_types]
        self.base_link, self.ee_link = str(base_link), str(ee_link)
        # as recorded where the arm was built: in a checkpoint, a path of the machine it was trained on
        self.recorded_urdf_path = None if urdf_path is None else str(urdf_path)
        self._urdf_here: tuple[Path | None] | None = None  # (installed_copy's answer,) once asked
        self.target = target
        self.target_dim = 3 if target == "position" else 7  # position, or position + quaternion (w, x, y, z)
        self.condition_dim = 3 if target == "position" else 9  # position / span, plus two rotation columns
        self.link_names = [str(name) for name in link_names]
        self.link_frames = [int(index) for index in link_frames]
        self.description = description  # the parsed URDF (meshes) when built from one; None from a config

        self._offsets = torch.tensor(joint_offsets, dtype=torch.float64)  # (J, 4, 4)
        axes = torch.tensor(joint_axes, dtype=torch.float64)
        self._axes = axes / axes.norm(dim=-1, keepdim=True)  # (J, 3)
        limits = torch.tensor(joint_limits, dtype=torch.float64)
        continuous = torch.tensor([kind == "continuous" for kind in self.joint_types])
        limits[continuous] = torch.tensor([-math.pi, math.pi], dtype=torch.float64)
        if not (limits[:, 0] <= limits[:, 1]).all():
            raise ValueError(f"joint_limits: expected lower <= upper for every joint, got {limits.tolist()}")
        self._limits = limits
        self._continuous = continuous
        self._ee_offset = torch.tensor(ee_offset, dtype=torch.float64)
        self._link_offsets = torch.tensor(link_offsets, dtype=torch.float64).reshape(-1, 4, 4)
        self._constants: dict = {}  # (dtype, device) -> the tensors forward kinematics multiplies by
        self._fused: FusedChain | None = None  # small_batch_kinematics(), once asked for

    # --- construction --------------------------------------------------------------------------
    @classmethod
    def from_description(cls, chain: ChainDescription, *, target: str = "pose") -> ChainArm:
        """Fold a parsed chain's fixed joints into the offsets of its movable joints."""
        names, types, offsets, axes, limits = [], [], [], [], []
        link_names, link_frames, link_offsets = [chain.base_link], [-1], [torch.eye(4, dtype=torch.float64).tolist()]
        pending = torch.eye(4, dtype=torch.float64)  # fixed offsets since the last movable joint
        for joint in chain.joints:
            pending = pending @ torch.tensor(origin_matrix(joint.origin), dtype=torch.float64)
            if joint.type == "fixed":
                link_frames.append(len(names) - 1)
                link_offsets.append(pending.tolist())
            else:
                names.append(joint.name)
                types.append(joint.type)
                offsets.append(pending.tolist())
                axes.append(list(joint.axis))
                limits.append([-math.pi, math.pi] if joint.type == "continuous" else [joint.lower, joint.upper])
                pending = torch.eye(4, dtype=torch.float64)
                link_frames.append(len(names) - 1)
                link_offsets.append(pending.tolist())
            link_names.append(joint.child)
        return cls(
            joint_names=names,
            joint_types=types,
            joint_offsets=offsets,
            joint_axes=axes,
            joint_limits=limits,
            ee_offset=pending.tolist(),
            link_names=link_names,
            link_frames=link_frames,
            link_offsets=link_offsets,
            base_link=chain.base_link,
            ee_link=chain.ee_link,
            urdf_path=chain.urdf_path,
            target=target,
            description=chain,
        )

    @classmethod
    def from_urdf(
        cls, urdf_path: str | Path, ee_link: str, *, target: str = "pose", base_link: str | None = None, package_dirs=()
    ) -> ChainArm:
        """Read the chain from `base_link` (default: the root of `ee_link`'s tree) to `ee_link` in a URDF file."""
        chain = read_chain(urdf_path, ee_link, base_link=base_link, package_dirs=package_dirs)
        return cls.from_description(chain, target=target)

    def to_config(self) -> dict:
        """Plain values only (lists, floats, strings): safe in a weights_only checkpoint."""
        return {
            "kind": self.kind,
            "joint_names": list(self.joint_names),
            "joint_types": list(self.joint_types),
            "joint_offsets": self._offsets.tolist(),
            "joint_axes": self._axes.tolist(),
            "joint_limits": self._limits.tolist(),
            "ee_offset": self._ee_offset.tolist(),
            "link_names": list(self.link_names),
            "link_frames": list(self.link_frames),
            "link_offsets": self._link_offsets.tolist(),
            "base_link": self.base_link,
            "ee_link": self.ee_link,
            "urdf_path": self.recorded_urdf_path,
            "target": self.target,
        }

    @classmethod
    def from_config(cls, config: dict) -> ChainArm:
        """Rebuild from `to_config()`; the URDF file need not exist."""
        if config.get("kind") != cls.kind:
            raise ValueError(f"config: expected kind 'chain', got {config.get('kind')!r}")
        return cls(**{key: value for key, value in config.items() if key != "kind"})

    def chain_description(self) -> ChainDescription | None:
        """The parsed URDF (links, meshes) for drawing: kept from construction, else re-read from
        `urdf_path` (an arm rebuilt from a checkpoint), else None when no such file is here.

        A checkpoint trained elsewhere records a path of that machine; a file of example-robot-data
        (the shipped robots') is found again in this environment's install of it.
        """
        if self.description is None and self.urdf_path is not None:
            self.description = read_chain(self.urdf_path, self.ee_link, base_link=self.base_link)
        return self.description

    @property
    def urdf_path(self) -> str | None:
        """The URDF file on this machine: the recorded path if it is here, else example-robot-data's installed
        copy of the file it names; None when neither is here (never a path of the machine it was trained on)."""
        if self.recorded_urdf_path is None:
            return None
        if self._urdf_here is None:
            self._urdf_here = (installed_copy(self.recorded_urdf_path),)
        found = self._urdf_here[0]
        return None if found is None else str(found)

    def __repr__(self) -> str:
        return f"ChainArm({self.base_link!r} -> {self.ee_link!r}, {self.num_joints} joints, target={self.target!r})"

    def __eq__(self, other) -> bool:
        return isinstance(other, ChainArm) and other.to_config() == self.to_config()

    def __hash__(self) -> int:
        return hash(("chain", tuple(self.joint_names), self.ee_link, self.target))

    # --- description ---------------------------------------------------------------------------
    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def ee_links(self) -> list[str]:
        """The end-effector links, one for a chain (a tree's several: ikdp/tree_arm.py)."""
        return [self.ee_link]

    num_links = num_joints  # moving links, one per joint: PlanarArm's name for the same count

    @property
    def joint_limits(self) -> torch.Tensor:
        """(J, 2) lower, upper; continuous joints report (-pi, pi) and wrap instead of clamping."""
        return self._limits.float()

    @property
    def continuous_joints(self) -> torch.Tensor:
        """(J,) bool: the joints without limits (URDF `continuous`), which wrap at +-pi instead of clamping."""
        return self._continuous.clone()

    @property
    def reach_center(self) -> torch.Tensor:
        """(3,) the first joint's origin: it never moves, so the end effector stays in a ball around it."""
        return self._offsets[0, :3, 3].float()

    @functools.cached_property
    def reach(self) -> tuple[float, float]:
        """(inner, outer) radius around `reach_center`: 0 (not known) and a bound on the distance.

        The bound is the triangle inequality along the chain: every offset after the first joint
        plus the end-effector offset, plus every prismatic joint's largest travel.
        """
        offsets = self._offsets[1:, :3, 3].norm(dim=-1).sum() + self._ee_offset[:3, 3].norm()
        prismatic = torch.tensor([kind == "prismatic" for kind in self.joint_types])
        travel = self._limits[prismatic].abs().amax(dim=-1).sum() if prismatic.any() else 0.0
        return 0.0, float(offsets + travel)

    @functools.cached_property
    def span(self) -> float:
        """A length scale: the sum of every offset's length along the chain (the base's included)."""
        return float(self._offsets[:, :3, 3].norm(dim=-1).sum() + self._ee_offset[:3, 3].norm())

    # a target counts as reached within 1 mm and 1 degree (a URDF's lengths are metres), whatever the arm's size
    position_tolerance = 1e-3  # metres
    rotation_tolerance = math.radians(1.0)  # radians, for pose targets

    # --- kinematics ----------------------------------------------------------------------------
    def _constants_like(self, like: torch.Tensor) -> dict:
        key = (like.dtype, like.device)
        if key not in self._constants:
            # built as normal tensors even inside inference mode (the sampler's), so that autograd can use
            # them later (obstacle guidance differentiates forward kinematics); inference mode reads them too
            with torch.inference_mode(False):
                self._constants[key] = self._build_constants(like)
        return self._constants[key]

    def _build_constants(self, like: torch.Tensor) -> dict:
        """The constant tensors forward kinematics multiplies by, in `like`'s dtype and device."""
        # Carry each joint's frame in a basis whose z is the joint's axis (rotation P_j, axis = its
        # third column): the joint's motion is then Rz(q) or a slide along z, applied to columns,
        # and the step from joint j-1 to joint j is one constant matrix M_j = P_{j-1}^T R_j P_j.
        bases = torch.stack([axis_basis(axis) for axis in self._axes])  # (J, 3, 3)
        before = torch.cat([torch.eye(3, dtype=torch.float64)[None], bases[:-1]])  # P_{j-1}, P_{-1} = I
        constants = {
            # M_j^T: left-multiplying the stacked columns of F by it gives the columns of F M_j.
            "steps_columns": (before.transpose(-1, -2) @ self._offsets[:, :3, :3] @ bases).transpose(-1, -2),
            "translations": (before.transpose(-1, -2) @ self._offsets[:, :3, 3:]).squeeze(-1),  # (J, 3)
            "bases": bases,
            "ee_rotation_columns": (bases[-1].T @ self._ee_offset[:3, :3]).T,
            "ee_translation": bases[-1].T @ self._ee_offset[:3, 3],
            "limits": self._limits,
            "continuous": self._continuous,
            "link_offsets": self._link_offsets,
            # made once per device: a host-to-device copy per call would break CUDA-graph capture
            "prismatic": torch.tensor([kind == "prismatic" for kind in self.joint_types]),
            "link_parents": torch.tensor(self.link_frames) + 1,  # -1 (base) -> row 0
            "reach_center": self._offsets[0, :3, 3],
        }
        return {
            name: value.to(device=like.device, dtype=like.dtype if value.is_floating_point() else value.dtype)
            for name, value in constants.items()
        }

    def _as_joints(self, joints) -> torch.Tensor:
        joints = torch.as_tensor(joints)
        if not joints.is_floating_point():
            joints = joints.float()
        if joints.ndim < 1 or joints.shape[-1] != self.num_joints:
            raise ValueError(f"joints: expected shape (..., {self.num_joints}), got {tuple(joints.shape)}")
        return joints

    def _joint_frames(self, joints: torch.Tensor, *, keep_frames: bool = True):
        """(..., J) -> per joint (when keep_frames) its axis-aligned frame F_j = R_j P_j after its motion
        (..., J, 3, 3), whose third column is the joint's world axis, and its origin (..., J, 3); then the
        end effector's rotation (..., 3, 3) and position (..., 3).

        Inside, the batch is the last dimension and a frame is stored column by column, (3, 3, B):
        a constant step M then touches all B frames in one (3, 3) x (3, 3B) product, and the joint's
        turn mixes two contiguous columns. Batch-first (B, 3, 3) products with K = 3 were 5x slower.
        """
        c = self._constants_like(joints)
        batch_shape = joints.shape[:-1]
        values = joints.reshape(-1, self.num_joints).T  # (J, B)
        count = values.shape[1]
        columns = c["steps_columns"][0][:, :, None].expand(3, 3, count)  # F_0 before its motion
        position = c["translations"][0][:, None].expand(3, count)  # (3, B)
        frames, origins = [], []
        for index, kind in enumerate(self.joint_types):
            if index > 0:
                flat = columns.reshape(3, 3 * count)  # row k: column k of every frame
                position = position + (c["translations"][index] @ flat).reshape(3, count)
                columns = (c["steps_columns"][index] @ flat).reshape(3, 3, count)
            if keep_frames:
                origins.append(position)
            value = values[index]  # (B,)
            if kind == "prismatic":
                position = position + columns[2] * value
            else:  # F <- F Rz(q): only the first two columns turn
                cos, sin = value.cos(), value.sin()
                first, second = columns[0], columns[1]
                columns = torch.stack([cos * first + sin * second, cos * second - sin * first, columns[2]])
            if keep_frames:
                frames.append(columns)
        flat = columns.reshape(3, 3 * count)
        ee_position = position + (c["ee_translation"] @ flat).reshape(3, count)
        ee_columns = (c["ee_rotation_columns"] @ flat).reshape(3, 3, count)

        def batch_first_matrix(stored: torch.Tensor) -> torch.Tensor:  # (..., 3 columns, 3 rows, B)
            return stored.movedim(-1, 0).transpose(-1, -2).reshape(*batch_shape, *stored.shape[:-3], 3, 3)

        ee_rotation = batch_first_matrix(ee_columns)
        ee_position = ee_position.T.reshape(*batch_shape, 3)
        if not keep_frames:
            return None, None, ee_rotation, ee_position
        frames = batch_first_matrix(torch.stack(frames))  # (..., J, 3, 3)
        origins = torch.stack(origins).movedim(-1, 0).reshape(*batch_shape, self.num_joints, 3)
        return frames, origins, ee_rotation, ee_position

    def forward_kinematics(self, joints) -> torch.Tensor:
        """(..., J) -> every joint's origin then the end effector, (..., J+1, 3), metres.

        The first point is the first joint's origin (where the moving chain starts, like the
        planar arm's base); the base link's own origin is `link_poses(...)[..., 0, :3, 3]`.
        """
        joints = self._as_joints(joints)
        _, origins, _, ee_position = self._joint_frames(joints)
        return torch.cat([origins, ee_position.unsqueeze(-2)], dim=-2)

    def end_effector_frame(self, joints) -> tuple[torch.Tensor, torch.Tensor]:
        """(..., J) -> the end-effector link's rotation (..., 3, 3) and position (..., 3) in the base frame."""
        _, _, rotation, position = self._joint_frames(self._as_joints(joints), keep_frames=False)
        return rotation, position

    def end_effector_pose(self, joints) -> torch.Tensor:
        """(..., J) -> position then unit quaternion (w, x, y, z) with w >= 0, (..., 7)."""
        rotation, position = self.end_effector_frame(joints)
        return torch.cat([position, matrix_to_quaternion(rotation)], dim=-1)

    def end_effector(self, joints) -> torch.Tensor:
        """(..., J) -> what a target describes: position (..., 3), or pose (..., 7) for pose targets."""
        if self.target == "position":
            return self.end_effector_frame(joints)[1]
        return self.end_effector_pose(joints)

    def link_poses(self, joints) -> torch.Tensor:
        """(..., J) -> every link on the chain (`link_names`) as a 4x4 in the base frame, (..., L, 4, 4)."""
        return self.link_poses_and_joint_frames(joints)[0]

    def link_poses_and_joint_frames(self, joints) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """`link_poses`, with the joints' axis-aligned frames (..., J, 3, 3) and origins (..., J, 3) the same
        kinematics pass made: what a sphere cover's depth and its gradient both read."""
        joints = self._as_joints(joints)
        axis_frames, origins, _, _ = self._joint_frames(joints)
        c = self._constants_like(joints)
        slides = torch.where(c["prismatic"], joints, torch.zeros_like(joints))  # a prismatic child sits at the slide
        batch = joints.shape[:-1]
        frames = torch.zeros(*batch, self.num_joints + 1, 4, 4, dtype=joints.dtype, device=joints.device)
        frames[..., 0, :3, :3] = torch.eye(3, dtype=joints.dtype, device=joints.device)
        frames[..., 1:, :3, :3] = axis_frames @ c["bases"].transpose(-1, -2)  # R_j = F_j P_j^T
        frames[..., 1:, :3, 3] = origins + axis_frames[..., :, 2] * slides[..., None]
        frames[..., :, 3, 3] = 1
        return frames[..., c["link_parents"], :, :] @ c["link_offsets"], axis_frames, origins

    def jacobian(self, joints) -> torch.Tensor:
        """(..., J) -> the geometric Jacobian, (..., 3, J) for position targets, (..., 6, J) for poses.

        Rows: d position / d q (revolute: axis x (p_ee - p_joint); prismatic: axis), then for
        poses the angular velocity per unit joint velocity (revolute: axis; prismatic: 0), all
        in the base frame. It matches `task_error`: a small step dq changes the error by -J dq.
        """
        joints = self._as_joints(joints)
        axis_frames, origins, _, ee_position = self._joint_frames(joints)
        return self._jacobian_from(joints, axis_frames, origins, ee_position)

    def _jacobian_from(self, joints, axis_frames, origins, ee_position) -> torch.Tensor:
        axes = axis_frames[..., :, 2]  # (..., J, 3) world axes: a joint's motion leaves its own axis alone
        revolute = ~self._constants_like(joints)["prismatic"]
        linear = torch.where(
            revolute[:, None], torch.linalg.cross(axes, ee_position.unsqueeze(-2) - origins, dim=-1), axes
        )  # (..., J, 3)
        if self.target == "position":
            return linear.transpose(-1, -2)
        angular = torch.where(revolute[:, None], axes, torch.zeros_like(axes))
        return torch.cat([linear, angular], dim=-1).transpose(-1, -2)

    def task_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        """What damped least squares drives to zero, (..., 3) or (..., 6).

        Position: target - current. Pose: that, then the axis-angle vector of R_target R_current^T
        in the base frame (radians; its norm is the geodesic rotation error).
        """
        rotation, position = self.end_effector_frame(joints)
        return self._task_error_from(rotation, position, targets)

    def _task_error_from(self, rotation, position, targets: torch.Tensor) -> torch.Tensor:
        position_error = targets[..., :3] - position
        if self.target == "position":
            return position_error
        relative = quaternion_multiply(targets[..., 3:7], quaternion_conjugate(matrix_to_quaternion(rotation)))
        return torch.cat([position_error, quaternion_to_axis_angle(relative)], dim=-1)

    def task_error_and_jacobian(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """`task_error` and `jacobian` from one pass of the forward kinematics: a refinement step and the
        denoiser's DLS feature need both, and the second pass was about a tenth of a refinement step's time."""
        joints = self._as_joints(joints)
        axis_frames, origins, rotation, position = self._joint_frames(joints)
        return self._task_error_from(rotation, position, targets), self._jacobian_from(
            joints, axis_frames, origins, position
        )

    def position_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        """Distance from the end effector to the target's position, (...), metres.

        Computed in float64 (refined poses land within 1e-6 m, below float32 FK's rounding),
        returned as float32. Targets may be (..., 3) or (..., 7).
        """
        return self.tip_and_rotation_errors(joints, targets[..., :3])[0]

    tip_error = position_error  # THE tip error of every arm: for a chain, the position error

    def rotation_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        """Geodesic angle between the end effector's rotation and the target's, (...), radians, in float64."""
        if targets.shape[-1] != 7:
            raise ValueError(f"targets: rotation_error needs pose targets (..., 7), got {tuple(targets.shape)}")
        return self.tip_and_rotation_errors(joints, targets)[1]

    def small_batch_kinematics(self) -> FusedChain:
        """This arm with its kinematics, Jacobian and errors as a few fused operations (ikdp/fused_chain.py):
        what a solve of a few poses on a CPU refines with; built once."""
        if self._fused is None:
            self._fused = FusedChain(self)
        return self._fused

    def tip_and_rotation_errors(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """`position_error` and, for pose targets (..., 7), `rotation_error`, from one float64 kinematics pass."""
        rotation, position = self.end_effector_frame(self._as_joints(joints).double())
        position_error = (position - targets[..., :3].double()).norm(dim=-1).float()
        if targets.shape[-1] != 7:
            return position_error, None
        relative = quaternion_multiply(targets[..., 3:7].double(), quaternion_conjugate(matrix_to_quaternion(rotation)))
        return position_error, quaternion_angle(relative).float()

    def with_default_constraints(self, constraints) -> list:
        """The constraints a solve runs: those given (a tree adds its self-collision check)."""
        return list(constraints)

    @property
    def chains(self) -> tuple[ChainArm]:
        """The serial chains of this arm: itself (a TreeArm has one per end effector)."""
        return (self,)

    def collision_spheres(self, held_joints=None):
        """The LinkSpheres obstacles meet: every moving link's sphere cover (ikdp/link_spheres.py)."""
        from ikdp.link_spheres import link_spheres

        return link_spheres(self, held_joints)

    def position_only_targets(self, constraint, targets) -> torch.Tensor:
        """`PositionOnly`'s targets (B, 7): the position given ((B, 3) or a pose's first three), an identity rotation
        as a placeholder the partial target replaces."""
        from ikdp.partial_targets import chain_position_only_targets

        return chain_position_only_targets(self, constraint, targets)

    def bind_position_only(self, constraint):
        """`PositionOnly.bind` for one end effector: the position counts, the rotation is free."""
        from ikdp.partial_targets import bind_chain_position_only

        return bind_chain_position_only(self, constraint)

    def errors_by_effector(self, joints, targets: torch.Tensor) -> None:
        """None: one end effector, whose errors are `tip_and_rotation_errors` (a tree gives one per end effector)."""
        return None

    def target_features(self, targets: torch.Tensor) -> torch.Tensor:
        """What a denoiser is conditioned on, (..., condition_dim).

        Position / span, then for poses the first two columns of the target's rotation matrix
        (the continuous 6-D rotation of Zhou et al. 2019: no sign ambiguity, unlike a quaternion).
        """
        position = targets[..., :3] / self.span
        if self.target == "position":
            return position
        rotation = quaternion_to_matrix(targets[..., 3:7])
        return torch.cat([position, rotation[..., :, 0], rotation[..., :, 1]], dim=-1)

    # --- targets -------------------------------------------------------------------------------
    def validate_targets(self, targets) -> torch.Tensor:
        """Array-like (B, 3) or (B, 7) -> float32 tensor; pose quaternions come back normalised.

        A quaternion whose norm is more than QUATERNION_TOLERANCE from 1 is refused, naming the
        row: silently normalising (0, 0, 0, 0.5) would hide a caller's unit mix-up.
        """
        tensor = validate_target_rows(targets, self.target_dim)
        if self.target == "position":
            return tensor
        if tensor.device.type == "cpu" and len(tensor) <= FEW_ROWS:  # one target's solve: NumPy's fixed cost
            rows = tensor.detach().numpy()
            norms = np.sqrt(np.square(rows[:, 3:].astype(np.float64)).sum(axis=-1))
            bad = np.abs(norms - 1) > QUATERNION_TOLERANCE
            if not bad.any():
                return torch.from_numpy(
                    np.concatenate([rows[:, :3], rows[:, 3:] / norms[:, None].astype(np.float32)], 1)
                )
            norms, bad = torch.from_numpy(norms), torch.from_numpy(bad)
        else:
            norms = tensor[:, 3:].double().norm(dim=-1)
            bad = (norms - 1).abs() > QUATERNION_TOLERANCE
        if bool(bad.any()):  # the row named only then: nonzero costs more than the check
            row = int(torch.nonzero(bad)[0, 0])
            raise ValueError(
                f"targets: row {row} has quaternion {tensor[row, 3:].tolist()} of norm {float(norms[row]):.6g}, "
                f"expected a unit quaternion (w, x, y, z)"
            )
        return torch.cat([tensor[:, :3], tensor[:, 3:] / norms[:, None].float()], dim=-1)

    def is_reachable(self, targets: torch.Tensor) -> torch.Tensor:
        """(B, target_dim) -> (B,) conservative: False only where the position is certainly out of reach.

        True means "inside the reach ball", not "reachable": joint limits and orientation are not checked.
        """
        center = self._constants_like(targets)["reach_center"]
        if few_rows_on_cpu(targets):  # one target's solve: NumPy's fixed cost, a fifth of torch's four operations
            offset = targets.numpy()[:, :3] - center.numpy()
            return torch.from_numpy(np.sqrt(np.square(offset).sum(axis=-1)) <= self.reach[1] + 1e-6)
        return (targets[..., :3] - center).norm(dim=-1) <= self.reach[1] + 1e-6

    def clamp_to_workspace(self, targets: torch.Tensor) -> torch.Tensor:
        """(..., target_dim) -> positions pulled onto the reach ball where outside it; quaternions unchanged."""
        center = self._constants_like(targets)["reach_center"]
        if few_rows_on_cpu(targets):  # as is_reachable
            rows = targets.numpy()
            offset = rows[:, :3] - center.numpy()
            radius = np.sqrt(np.square(offset).sum(axis=-1, keepdims=True))
            scale = np.minimum(self.reach[1] / np.maximum(radius, 1e-12), 1.0)  # Python numbers keep the dtype
            return torch.from_numpy(np.concatenate((center.numpy() + offset * scale, rows[:, 3:]), axis=-1))
        offset = targets[..., :3] - center
        radius = offset.norm(dim=-1, keepdim=True)
        scale = torch.clamp(self.reach[1] / radius.clamp_min(1e-12), max=1.0)
        return torch.cat([center + offset * scale, targets[..., 3:]], dim=-1)

    # --- poses ---------------------------------------------------------------------------------
    def random_poses(self, count: int, *, generator: torch.Generator | None = None) -> torch.Tensor:
        """`count` poses with every joint uniform within its limits, (count, J), float32, on the generator's
        device (a training's data made on its GPU: no host copy)."""
        if count < 0:
            raise ValueError(f"count: expected a number of poses >= 0, got {count}")
        unit = torch.rand((count, self.num_joints), generator=generator, device=drawing_device(generator))
        limits = self._constants_like(unit)["limits"]
        return limits[:, 0] + unit * (limits[:, 1] - limits[:, 0])

    def random_poses_like(self, like: torch.Tensor, *, generator: torch.Generator | None = None) -> torch.Tensor:
        """Poses shaped like `like` (..., J), uniform within the limits, on its device and in its dtype, from a
        generator on that device: the limits are the per-device constants, so nothing is copied from the host
        (a CUDA graph captures the draw)."""
        limits = self._constants_like(like)["limits"]
        unit = torch.rand(like.shape, generator=generator, device=like.device, dtype=like.dtype)
        return limits[:, 0] + unit * (limits[:, 1] - limits[:, 0])
