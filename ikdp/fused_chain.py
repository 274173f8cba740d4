"""A chain's kinematics and refinement for a few poses at a time: a handful of tensor operations whatever the
joint count.

`ChainArm`'s own kinematics walk the joints one by one, a few small tensor operations each, which pays
off for a thousand poses (each operation touches them all at once) but costs a fixed few microseconds an
operation: for one target's K = 16 poses that walk, the quaternion conversions and the stacking were most of
a solve's time, the network a few percent. Here the same quantities come from:
- the products of per-joint 4x4 transforms (each a constant plus cos q and sin q times constants) taken as a
  prefix scan, log2 J batched matrix products into preallocated buffers (no stacking, no concatenation:
  torch.cat alone cost as much as a 16 x 7 x 4 x 4 matrix product on one CPU thread);
- the rotation error from one 3x3 product R_target R^T and Shepperd's quaternion of it written as one
  constant linear map, where `ChainArm` converts the rotation to a quaternion and multiplies quaternions;
- the damped least-squares refinement (`refine`) on the same kernels written in NumPy (ikdp/small_refine.py:
  a few hundred numbers an array, where NumPy's fixed cost an operation is a fraction of torch's), the target
  rotations computed once a solve and both candidates of a blocked pose compared in one kinematics pass.
The arithmetic is the same up to rounding: tests hold every quantity to 1e-9 of `ChainArm`'s in float64
and the refined poses to the general refinement's.

`FusedChain` wraps a `ChainArm` and answers what damped least squares, the restarts and the solver's error
check ask of an arm (the rest is the arm's own); `ChainArm.small_batch_kinematics()` builds it once. The
solver uses it for solves of at most `FUSED_ROWS` poses on a CPU: above that the arm's own column layout,
whose operations each cover the whole batch, is the faster of the two.
"""

from __future__ import annotations

import numpy as np
import torch

from ikdp.refine import RefineTask, damped_least_squares, dls_step
from ikdp.small_refine import RefineScores, SmallRefine

FUSED_ROWS = 256  # poses a call: at most this many go through FusedChain on a CPU

# Shepperd's method (rotations.matrix_to_quaternion) as a linear map: the flattened rotation (9,) times SHEPPERD
# plus a constant gives the four candidate rows (4, 4), row i being 2 q_i q (its diagonal 4 q_i^2).
_CANDIDATES = (  # per candidate entry: (constant, [(matrix row * 3 + column, coefficient), ...])
    ((1, [(0, 1), (4, 1), (8, 1)]), (0, [(7, 1), (5, -1)]), (0, [(2, 1), (6, -1)]), (0, [(3, 1), (1, -1)])),
    ((0, [(7, 1), (5, -1)]), (1, [(0, 1), (4, -1), (8, -1)]), (0, [(3, 1), (1, 1)]), (0, [(2, 1), (6, 1)])),
    ((0, [(2, 1), (6, -1)]), (0, [(3, 1), (1, 1)]), (1, [(0, -1), (4, 1), (8, -1)]), (0, [(7, 1), (5, 1)])),
    ((0, [(3, 1), (1, -1)]), (0, [(2, 1), (6, 1)]), (0, [(7, 1), (5, 1)]), (1, [(0, -1), (4, -1), (8, 1)])),
)
# rotations.quaternion_to_matrix as a quadratic form: the outer product q q^T (16,) times QUADRATIC plus the
# identity, the same expressions (1 - 2 (y^2 + z^2), 2 (x y - w z), ...) for a unit quaternion q = (w, x, y, z).
_QUADRATIC = (  # matrix entry -> [(i * 4 + j of q_i q_j, coefficient)]
    [(10, -2), (15, -2)],
    [(6, 2), (3, -2)],
    [(7, 2), (2, 2)],
    [(6, 2), (3, 2)],
    [(5, -2), (15, -2)],
    [(11, 2), (1, -2)],
    [(7, 2), (2, -2)],
    [(11, 2), (1, 2)],
    [(5, -2), (10, -2)],
)


def small_batch(rows: int, device: torch.device) -> bool:
    """Whether a call over `rows` poses on `device` goes through `FusedChain` (FUSED_ROWS, on a CPU)."""
    return rows <= FUSED_ROWS and torch.device(device).type == "cpu"


class FusedChain:
    """A `ChainArm`'s end-effector kinematics, Jacobian, errors and refinement for small batches (module
    docstring). Everything else (limits, tolerances, target handling) is the arm's own, read through."""

    def __init__(self, arm):
        self.arm = arm
        self._constants: dict = {}
        self._small_refine: SmallRefine | None = None  # the refinement's NumPy loop, once asked for

    def __getattr__(self, name: str):
        return getattr(self.arm, name)  # what the arm answers alike for any batch

    def _constants_like(self, like: torch.Tensor) -> dict:
        key = (like.dtype, like.device)
        if key not in self._constants:
            with torch.inference_mode(False):
                self._constants[key] = self._build_constants(like)
        return self._constants[key]

    def _build_constants(self, like: torch.Tensor) -> dict:
        """Joint j's transform after its motion, L_j Z(q_j), as fixed_j + cos q cosine_j + sin q sine_j (+ q slide_j
        for a prismatic joint); L_j the arm's constant step from joint j-1's axis frame to joint j's."""
        arm = self.arm
        c = arm._constants_like(torch.empty(0, dtype=torch.float64))
        steps = torch.zeros(arm.num_joints, 4, 4, dtype=torch.float64)
        steps[:, :3, :3] = c["steps_columns"].transpose(-1, -2)
        steps[:, :3, 3] = c["translations"]
        steps[:, 3, 3] = 1
        prismatic = c["prismatic"]
        revolute = ~prismatic
        fixed, cosine, sine, slide = steps.clone(), torch.zeros_like(steps), torch.zeros_like(steps), None
        # F Rz(q) turns the first two columns: cos q (c0, c1) + sin q (c1, -c0)
        fixed[revolute, :, :2] = 0
        cosine[revolute, :, 0], cosine[revolute, :, 1] = steps[revolute, :, 0], steps[revolute, :, 1]
        sine[revolute, :, 0], sine[revolute, :, 1] = steps[revolute, :, 1], -steps[revolute, :, 0]
        if prismatic.any():  # a slide along z moves the origin by q times the third column
            slide = torch.zeros_like(steps)
            slide[prismatic, :, 3] = steps[prismatic, :, 2]
        end = torch.eye(4, dtype=torch.float64)
        end[:3, :3] = c["ee_rotation_columns"].T
        end[:3, 3] = c["ee_translation"]
        shepperd = torch.zeros(9, 16, dtype=torch.float64)
        shepperd_constant = torch.zeros(16, dtype=torch.float64)
        for row, entries in enumerate(_CANDIDATES):
            for column, (constant, terms) in enumerate(entries):
                shepperd_constant[row * 4 + column] = constant
                for index, coefficient in terms:
                    shepperd[index, row * 4 + column] = coefficient
        quadratic = torch.zeros(16, 9, dtype=torch.float64)
        for entry, terms in enumerate(_QUADRATIC):
            for index, coefficient in terms:
                quadratic[index, entry] = coefficient
        floats = {
            "fixed": fixed[:, None],  # (J, 1, 4, 4): the joint dimension leads, each joint's poses contiguous
            "cosine": cosine[:, None],
            "sine": sine[:, None],
            "end": end,
            "shepperd": shepperd,
            "shepperd_constant": shepperd_constant,
            "quadratic": quadratic,
            "identity9": torch.eye(3, dtype=torch.float64).reshape(9),
            "lower": c["limits"][:, 0],
            "upper": c["limits"][:, 1],
            # 0-dim tensors for the numbers the kernels use: a Python number in an operation is wrapped into a
            # tensor at each call (x < 0 took 7.7 us on one Xeon thread, x < zero 1.2 us)
            "zero": torch.tensor(0.0, dtype=torch.float64),
            "one": torch.tensor(1.0, dtype=torch.float64),
            "minus_one": torch.tensor(-1.0, dtype=torch.float64),
            "two": torch.tensor(2.0, dtype=torch.float64),
            "small_angle": torch.tensor(1e-6, dtype=torch.float64),  # rotations.quaternion_to_axis_angle's
        }
        if slide is not None:
            floats["slide"] = slide[:, None]
            floats["prismatic"] = prismatic.to(torch.float64)
        constants = {name: value.to(device=like.device, dtype=like.dtype) for name, value in floats.items()}
        constants["revolute"] = revolute.to(like.device) if prismatic.any() else None
        constants["continuous"] = c["continuous"].to(like.device) if bool(c["continuous"].any()) else None
        constants["limited"] = (~c["continuous"]).to(like.device)
        return constants

    # --- the kernels, on rows (N, J) ------------------------------------------------------------
    def _frames(self, joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, J) -> each joint's axis frame after its motion, (J, N, 4, 4) (third column: the joint's world axis,
        fourth: its origin, past the slide for a prismatic joint), and the end effector's (N, 4, 4)."""
        c = self._constants_like(joints)
        angle = joints.T[:, :, None, None]  # (J, N, 1, 1)
        count, span = joints.shape[-1], 1
        local = torch.empty(count, len(joints), 4, 4, dtype=joints.dtype, device=joints.device)
        other = torch.empty_like(local)
        torch.addcmul(c["fixed"], angle.cos(), c["cosine"], out=local).addcmul_(angle.sin(), c["sine"])
        if "slide" in c:
            local.addcmul_(angle * c["prismatic"][:, None, None, None], c["slide"])
        while span < count:  # Hillis-Steele: after the pass with span s, entry j is the product of the 2 s up to it
            other[:span].copy_(local[:span])
            # 3-D views of contiguous blocks: torch.matmul on 4-D slices copied them first
            torch.bmm(local[:-span].view(-1, 4, 4), local[span:].view(-1, 4, 4), out=other[span:].view(-1, 4, 4))
            local, other = other, local
            span *= 2
        return local, torch.mm(local[-1].view(-1, 4), c["end"]).view(-1, 4, 4)

    def _target_rotations(self, targets: torch.Tensor) -> torch.Tensor:
        """(N, 7) -> (N, 3, 3), from the quaternion normalised in this dtype (a float32 unit quaternion is one to
        1e-7 only; `ChainArm`'s errors are blind to the quaternion's norm, a rotation matrix is not)."""
        c = self._constants_like(targets)
        quaternion = targets[:, 3:7]
        quaternion = quaternion / torch.linalg.vector_norm(quaternion, dim=-1, keepdim=True)
        outer = (quaternion[:, :, None] * quaternion[:, None, :]).view(-1, 16)
        return torch.addmm(c["identity9"], outer, c["quadratic"]).view(-1, 3, 3)

    def _relative_quaternion(self, end: torch.Tensor, target_rotations: torch.Tensor) -> torch.Tensor:
        """R_target R^T as a unit quaternion (N, 4) with w >= 0, by rotations.matrix_to_quaternion's choice."""
        c = self._constants_like(end)
        relative = torch.bmm(target_rotations, end[:, :3, :3].transpose(-1, -2)).view(-1, 9)
        candidates = torch.addmm(c["shepperd_constant"], relative, c["shepperd"]).view(-1, 4, 4)
        best = candidates.diagonal(dim1=-2, dim2=-1).argmax(dim=-1)
        chosen = candidates.gather(1, best[:, None, None].expand(-1, 1, 4))[:, 0]
        # q and -q are one rotation: w >= 0, as rotations.canonical_quaternion (w = 0 kept)
        sign = torch.where(chosen[:, :1] < c["zero"], c["minus_one"], c["one"])
        return chosen * (sign / torch.linalg.vector_norm(chosen, dim=-1, keepdim=True))

    def _task_error(self, end: torch.Tensor, targets: torch.Tensor, target_rotations: torch.Tensor | None):
        """(N, 4, 4), (N, target_dim) -> ChainArm.task_error (N, E)."""
        position_error = targets[:, :3] - end[:, :3, 3]
        if target_rotations is None:
            return position_error
        c = self._constants_like(end)
        quaternion = self._relative_quaternion(end, target_rotations)
        vector, cosine_half = quaternion[:, 1:], quaternion[:, :1]
        sine_half = torch.linalg.vector_norm(vector, dim=-1, keepdim=True)
        small = sine_half < c["small_angle"]  # rotations.quaternion_to_axis_angle's small-angle branch
        two = c["two"]
        factor = torch.where(small, two / cosine_half, two * torch.atan2(sine_half, cosine_half) / sine_half)
        error = torch.empty(len(end), 6, dtype=end.dtype, device=end.device)
        error[:, :3] = position_error
        torch.mul(vector, factor, out=error[:, 3:])
        return error

    def _jacobian(self, joints: torch.Tensor, frames: torch.Tensor, end: torch.Tensor) -> torch.Tensor:
        """(N, J), the frames -> ChainArm.jacobian (N, E, J)."""
        c = self._constants_like(joints)
        axes = frames[:, :, :3, 2].permute(1, 2, 0)  # (N, 3, J)
        origins = frames[:, :, :3, 3].permute(1, 2, 0)
        revolute = c["revolute"]
        if revolute is not None:  # a slid joint's frame sits past its origin by q along its axis
            origins = origins - axes * (joints * c["prismatic"])[:, None, :]
        rows = 3 if self.arm.target == "position" else 6
        jacobian = torch.empty(len(joints), rows, joints.shape[-1], dtype=joints.dtype, device=joints.device)
        torch.linalg.cross(axes, end[:, :3, 3:] - origins, dim=1, out=jacobian[:, :3])
        if revolute is not None:  # a slide moves the end effector along its axis and turns nothing
            jacobian[:, :3] = torch.where(revolute, jacobian[:, :3], axes)
        if rows == 6:
            jacobian[:, 3:] = axes if revolute is None else axes * revolute
        return jacobian

    def _rows(self, joints, targets: torch.Tensor | None = None):
        """joints (..., J) and targets broadcast to them -> rows (N, J), (N, target_dim), the batch shape."""
        joints = self.arm._as_joints(joints)
        batch = joints.shape[:-1]
        rows = joints.reshape(-1, joints.shape[-1])
        if targets is None:
            return rows, None, batch
        targets = targets.to(joints.dtype).expand(*batch, targets.shape[-1]).reshape(len(rows), -1)
        return rows, targets, batch

    def _rotations_of(self, targets: torch.Tensor) -> torch.Tensor | None:
        return None if self.arm.target == "position" else self._target_rotations(targets)

    # --- ChainArm's kinematics ------------------------------------------------------------------
    def end_effector_frame(self, joints) -> tuple[torch.Tensor, torch.Tensor]:
        """(..., J) -> the end effector's rotation (..., 3, 3) and position (..., 3), as `ChainArm`'s."""
        rows, _, batch = self._rows(joints)
        _, end = self._frames(rows)
        return end[:, :3, :3].reshape(*batch, 3, 3), end[:, :3, 3].reshape(*batch, 3)

    def jacobian(self, joints) -> torch.Tensor:
        rows, _, batch = self._rows(joints)
        frames, end = self._frames(rows)
        jacobian = self._jacobian(rows, frames, end)
        return jacobian.reshape(*batch, *jacobian.shape[1:])

    def task_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        rows, targets, batch = self._rows(joints, targets)
        _, end = self._frames(rows)
        error = self._task_error(end, targets, self._rotations_of(targets))
        return error.reshape(*batch, -1)

    def task_error_and_jacobian(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        rows, targets, batch = self._rows(joints, targets)
        frames, end = self._frames(rows)
        error = self._task_error(end, targets, self._rotations_of(targets))
        jacobian = self._jacobian(rows, frames, end)
        return error.reshape(*batch, -1), jacobian.reshape(*batch, *jacobian.shape[1:])

    def task_error_and_dls_step(self, joints, targets: torch.Tensor, damping_squared: float):
        """joints (..., J), targets broadcast to them -> `task_error` (..., E) and `refine.dls_step`'s step (..., J):
        on a CPU by NumPy's kernels in float64 (half the time of torch's for one target's K poses), returned in the
        joints' dtype."""
        rows, targets, batch = self._rows(joints, targets)
        if rows.device.type == "cpu":
            error, step = self.small_refine().error_and_step(rows, targets, damping_squared)
        else:
            frames, end = self._frames(rows)
            error = self._task_error(end, targets, self._rotations_of(targets))
            step = dls_step(self._jacobian(rows, frames, end), error, damping_squared)
        return error.reshape(*batch, -1), step.reshape(*batch, -1)

    def target_features(self, targets: torch.Tensor) -> torch.Tensor:
        """`ChainArm.target_features` (..., condition_dim), the rotation's columns from `_target_rotations`'s one
        product where the arm's quaternion_to_matrix takes a dozen operations."""
        arm = self.arm
        if arm.target == "position":
            return arm.target_features(targets)
        rows = targets.reshape(-1, targets.shape[-1])
        if rows.device.type == "cpu" and not rows.requires_grad:  # the same operations in NumPy: a third of the time
            c = self._constants_like(rows)
            values = rows.numpy()
            quaternion = values[:, 3:7] / np.sqrt(np.square(values[:, 3:7]).sum(axis=-1, keepdims=True))
            outer = (quaternion[:, :, None] * quaternion[:, None, :]).reshape(-1, 16)
            rotation = (outer @ c["quadratic"].numpy() + c["identity9"].numpy()).reshape(-1, 3, 3)
            features = np.concatenate((values[:, :3] / arm.span, rotation[:, :, 0], rotation[:, :, 1]), axis=-1)
            return torch.from_numpy(features).reshape(*targets.shape[:-1], -1)
        rotation = self._target_rotations(rows)
        features = torch.cat((rows[:, :3] / arm.span, rotation[:, :, 0], rotation[:, :, 1]), dim=-1)
        return features.reshape(*targets.shape[:-1], -1)

    def tip_and_rotation_errors(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """`ChainArm.tip_and_rotation_errors`: the position and (pose targets) rotation errors, in float64."""
        rows, targets, batch = self._rows(self.arm._as_joints(joints).double(), targets)
        if rows.device.type == "cpu":  # NumPy's kernels: a fraction of torch's fixed cost an operation
            position, rotation = self.small_refine().errors(rows, targets)
            return position.reshape(batch), None if rotation is None else rotation.reshape(batch)
        _, end = self._frames(rows)
        position = torch.linalg.vector_norm(end[:, :3, 3] - targets[:, :3], dim=-1).float().reshape(batch)
        if targets.shape[-1] != 7:
            return position, None
        quaternion = self._relative_quaternion(end, self._target_rotations(targets))
        angle = torch.atan2(torch.linalg.vector_norm(quaternion[:, 1:], dim=-1), quaternion[:, 0])
        angle = angle * self._constants_like(angle)["two"]
        return position, angle.float().reshape(batch)

    def position_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        return self.tip_and_rotation_errors(joints, targets[..., :3])[0]

    tip_error = position_error

    def rotation_error(self, joints, targets: torch.Tensor) -> torch.Tensor:
        if targets.shape[-1] != 7:
            raise ValueError(f"targets: rotation_error needs pose targets (..., 7), got {tuple(targets.shape)}")
        return self.tip_and_rotation_errors(joints, targets)[1]

    def small_refine(self) -> SmallRefine:
        """The NumPy kernels of the refinement and the error check (ikdp/small_refine.py), built once."""
        if self._small_refine is None:
            constants = self._constants_like(torch.empty(0, dtype=torch.float64))
            self._small_refine = SmallRefine(constants, self.arm.span, self.arm.target == "pose")
        return self._small_refine

    # --- refinement -----------------------------------------------------------------------------
    def refine(
        self,
        joints: torch.Tensor,
        targets: torch.Tensor,
        *,
        steps: int = 5,
        task: RefineTask | None = None,
        damping: float = 1e-3,
        max_miss_fraction: float = 0.2,
    ) -> torch.Tensor:
        """`refine.damped_least_squares` on these kinematics: the same steps, clamps, limits and choice of a blocked
        pose's two candidates (`better_of`), in float64, by NumPy on a CPU (no gradient flows through it); a `task`
        (constraints) takes the general loop."""
        if task is not None:
            return damped_least_squares(self, joints, targets, steps=steps, task=task, damping=damping)
        if not isinstance(steps, int) or steps < 0:
            raise ValueError(f"refine steps: expected a non-negative integer, got {steps!r}")
        if joints.device.type != "cpu":  # the NumPy loop is a CPU's; elsewhere the general one
            return damped_least_squares(
                self, joints, targets, steps=steps, damping=damping, max_miss_fraction=max_miss_fraction
            )
        dtype, batch = joints.dtype, joints.shape[:-1]
        rows, targets, _ = self._rows(joints, targets)
        refined = self.small_refine().refine(rows, targets, steps, damping, max_miss_fraction)
        return refined.to(dtype).reshape(*batch, -1)

    def refine_scored(
        self,
        joints: torch.Tensor,
        targets: torch.Tensor,
        *,
        steps: int,
        damping: float = 1e-3,
        max_miss_fraction: float = 0.2,
        until_reached: bool = False,
    ) -> tuple[torch.Tensor, RefineScores | None]:
        """`refine` (no task) of joints (B, K, J) toward targets (B, K, target_dim), and on a CPU the errors its own
        kinematics measured on the way (`RefineScores`, each (B, K)): a one-target solve's error checks read them
        where they would take two more kinematics passes. Elsewhere (None) the caller measures them.
        `until_reached`: stop before a step once every target has a pose within the arm's tolerances."""
        if joints.device.type != "cpu":
            refined = damped_least_squares(
                self,
                joints,
                targets,
                steps=steps,
                damping=damping,
                max_miss_fraction=max_miss_fraction,
                until_reached=until_reached,
            )
            return refined, None
        if not isinstance(steps, int) or steps < 0:
            raise ValueError(f"refine steps: expected a non-negative integer, got {steps!r}")
        dtype, batch = joints.dtype, joints.shape[:-1]
        rows, targets, _ = self._rows(joints, targets)
        refined, scores = self.small_refine().refine_scored(
            rows,
            targets,
            steps,
            damping,
            max_miss_fraction,
            scored=True,
            output_dtype=dtype,
            until_within=(joints.shape[-2], self.arm.position_tolerance, self.arm.rotation_tolerance)
            if until_reached
            else None,
        )
        shaped = lambda value: None if value is None else value.reshape(batch)  # noqa: E731
        scores = RefineScores(shaped(scores.position), shaped(scores.rotation), shaped(scores.first_position))
        return refined.to(dtype).reshape(*batch, -1), scores
