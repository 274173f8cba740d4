"""Damped least squares for a few poses of a chain on a CPU, in NumPy: `FusedChain.refine`'s loop.

The same steps as `refine.damped_least_squares` without a task, on `FusedChain`'s fused kinematics (a prefix scan
of per-joint 4x4 transforms, the rotation error by one constant linear map), in float64. For one target's K = 16
poses every array is a few hundred numbers, so a step's cost is the fixed cost of its operations, and NumPy's is
a fraction of torch's on one CPU thread (one Xeon thread: an element-wise operation 0.6 us against 1.3, a batch
of small matrix products 5 against 12, a batched 6 x 6 solve 18 against 34, a concatenation 1.5 against 24):
the refinement is most of a one-target solve's time after the network. Tests hold its poses to the general
loop's.

Where a C compiler builds ikdp/chain_refine_kernel.c (ikdp/compiled_chain.py), the loop and the denoiser's
error-and-step feature run there instead, pose by pose in one call each, the same numbers to rounding: a fifth of
the loop's time on a Panda target's 16 poses. This NumPy loop is the fallback, and the reference the kernel is
tested against.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ikdp.compiled_chain import CompiledChain, compiled_chain


def norm(vectors: np.ndarray) -> np.ndarray:
    """Euclidean norms over the last axis, kept: np.linalg.norm's arithmetic without its Python-level checks (a
    fifth of the loop's time went to them)."""
    return np.sqrt(np.add.reduce(vectors * vectors, axis=-1, keepdims=True))


class SmallRefine:
    """The constants of one chain as NumPy arrays (from `FusedChain`'s float64 ones), and the refinement loop."""

    def __init__(self, constants: dict, span: float, pose_targets: bool):
        def array(name: str) -> np.ndarray | None:
            value = constants.get(name)
            return None if value is None else value.detach().cpu().numpy()

        self.fixed, self.cosine, self.sine, self.end = array("fixed"), array("cosine"), array("sine"), array("end")
        self.slide = array("slide")
        self.prismatic = array("prismatic")
        self.revolute = array("revolute")
        self.continuous = array("continuous")
        self.limited = array("limited")
        self.lower, self.upper = array("lower"), array("upper")
        self.shepperd, self.shepperd_constant = array("shepperd"), array("shepperd_constant")
        self.quadratic, self.identity9 = array("quadratic"), array("identity9")
        self.span = span
        self.pose_targets = pose_targets
        self.eye = np.eye(6 if pose_targets else 3)
        self._compiled: CompiledChain | None | bool = False  # False: not asked for yet; None: NumPy's loop runs

    def compiled(self) -> CompiledChain | None:
        """The loop and the feature as compiled C (ikdp/compiled_chain.py), built once; None where it cannot be."""
        if self._compiled is False:
            self._compiled = compiled_chain(self)
        return self._compiled

    # --- kinematics, as FusedChain's kernels ---------------------------------------------------
    def frames(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, J) -> each joint's axis frame (J, N, 4, 4) and the end effector's (N, 4, 4)."""
        angle = rows.T[:, :, None, None]
        local = self.fixed + np.cos(angle) * self.cosine + np.sin(angle) * self.sine
        if self.slide is not None:
            local += (angle * self.prismatic[:, None, None, None]) * self.slide
        count, span = rows.shape[1], 1
        other = np.empty_like(local)
        while span < count:  # Hillis-Steele prefix products, as FusedChain._frames
            other[:span] = local[:span]
            np.matmul(local[:-span], local[span:], out=other[span:])
            local, other = other, local
            span *= 2
        return local, local[-1] @ self.end

    def target_rotations(self, targets: np.ndarray) -> np.ndarray:
        quaternion = targets[:, 3:7] / norm(targets[:, 3:7])
        outer = (quaternion[:, :, None] * quaternion[:, None, :]).reshape(-1, 16)
        return (outer @ self.quadratic + self.identity9).reshape(-1, 3, 3)

    def relative_quaternion(self, end: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        """R_target R^T as a unit quaternion (N, 4), w >= 0 (FusedChain._relative_quaternion)."""
        relative = (rotations @ end[:, :3, :3].transpose(0, 2, 1)).reshape(-1, 9)
        candidates = (relative @ self.shepperd + self.shepperd_constant).reshape(-1, 4, 4)
        best = candidates.diagonal(axis1=1, axis2=2).argmax(axis=-1)
        chosen = candidates[np.arange(len(candidates)), best]
        sign = np.where(chosen[:, :1] < 0, -1.0, 1.0)  # w >= 0, as rotations.canonical_quaternion
        return chosen * (sign / norm(chosen))

    def task_error(self, end: np.ndarray, targets: np.ndarray, rotations: np.ndarray | None) -> np.ndarray:
        position = targets[:, :3] - end[:, :3, 3]
        if rotations is None:
            return position
        quaternion = self.relative_quaternion(end, rotations)
        vector, cosine_half = quaternion[:, 1:], quaternion[:, :1]
        sine_half = norm(vector)
        small = sine_half < 1e-6  # rotations.quaternion_to_axis_angle's small-angle branch
        safe = np.where(small, 1.0, sine_half)
        factor = np.where(small, 2 / cosine_half, 2 * np.arctan2(sine_half, cosine_half) / safe)
        return np.concatenate((position, vector * factor), axis=1)

    def jacobian(self, rows: np.ndarray, frames: np.ndarray, end: np.ndarray) -> np.ndarray:
        axes = frames[:, :, :3, 2].transpose(1, 2, 0)  # (N, 3, J)
        origins = frames[:, :, :3, 3].transpose(1, 2, 0)
        if self.revolute is not None:  # a slid joint's frame sits past its origin by q along its axis
            origins = origins - axes * (rows * self.prismatic)[:, None, :]
        lever = end[:, :3, 3:] - origins
        jacobian = np.empty((len(rows), 6 if self.pose_targets else 3, rows.shape[1]))
        a0, a1, a2 = axes[:, 0], axes[:, 1], axes[:, 2]
        b0, b1, b2 = lever[:, 0], lever[:, 1], lever[:, 2]
        jacobian[:, 0] = a1 * b2 - a2 * b1
        jacobian[:, 1] = a2 * b0 - a0 * b2
        jacobian[:, 2] = a0 * b1 - a1 * b0
        if self.revolute is not None:  # a slide moves the end effector along its axis and turns nothing
            jacobian[:, :3] = np.where(self.revolute, jacobian[:, :3], axes)
        if self.pose_targets:
            jacobian[:, 3:] = axes if self.revolute is None else axes * self.revolute
        return jacobian

    def normalized(self, rows: np.ndarray) -> np.ndarray:
        clamped = np.minimum(np.maximum(rows, self.lower), self.upper)
        if self.continuous is None:
            return clamped
        wrapped = np.remainder(rows + np.pi, 2 * np.pi) - np.pi  # kinematics.wrap_angle: into (-pi, pi]
        wrapped = np.where(wrapped == -np.pi, np.pi, wrapped)
        return np.where(self.continuous, wrapped, clamped)

    def dls(self, jacobian: np.ndarray, error: np.ndarray, damping_squared: float) -> np.ndarray:
        """refine.dls_step: J^T (J J^T + lambda^2 I)^-1 e, (N, J)."""
        gram = jacobian @ jacobian.transpose(0, 2, 1) + damping_squared * self.eye
        solved = np.linalg.solve(gram, error[:, :, None])
        return (jacobian.transpose(0, 2, 1) @ solved)[:, :, 0]

    def errors(self, rows: torch.Tensor, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """rows (N, J), targets (N, target_dim) -> ChainArm.tip_and_rotation_errors: the position error and, for
        pose targets (N, 7), the rotation's geodesic angle, computed in float64, returned as float32 (N,)."""
        joints = rows.detach().double().numpy()
        goals = targets.detach().double().numpy()
        _, end = self.frames(joints)
        position = torch.from_numpy(norm(end[:, :3, 3] - goals[:, :3])[:, 0]).float()
        if goals.shape[1] != 7:
            return position, None
        quaternion = self.relative_quaternion(end, self.target_rotations(goals))
        angle = 2 * np.arctan2(norm(quaternion[:, 1:])[:, 0], quaternion[:, 0])
        return position, torch.from_numpy(angle).float()

    def error_and_step(self, rows: torch.Tensor, targets: torch.Tensor, damping_squared: float):
        """rows (N, J), targets (N, target_dim) -> the task error (N, E) and the damped least-squares step
        (N, J), computed in float64, returned in the rows' dtype: what the robot denoiser reads as features."""
        joints = rows.detach().double().numpy()
        goals = targets.detach().double().numpy()
        compiled = self.compiled()
        if compiled is not None:
            error, step = compiled.error_and_step(joints, goals, damping_squared)
        else:
            frames, end = self.frames(joints)
            error = self.task_error(end, goals, self.target_rotations(goals) if self.pose_targets else None)
            step = self.dls(self.jacobian(joints, frames, end), error, damping_squared)
        return torch.from_numpy(error).to(rows.dtype), torch.from_numpy(step).to(rows.dtype)

    # --- the loop --------------------------------------------------------------------------------
    def refine(
        self, rows: torch.Tensor, targets: torch.Tensor, steps: int, damping: float, max_miss_fraction: float
    ) -> torch.Tensor:
        """rows (N, J), targets (N, target_dim), any float dtype on the CPU -> refined rows (N, J) in float64."""
        return self.refine_scored(rows, targets, steps, damping, max_miss_fraction)[0]

    def refine_scored(
        self,
        rows: torch.Tensor,
        targets: torch.Tensor,
        steps: int,
        damping: float,
        max_miss_fraction: float,
        *,
        scored: bool = False,
        output_dtype: torch.dtype = torch.float64,
        until_within: tuple[int, float, float] | None = None,
    ) -> tuple[torch.Tensor, RefineScores | None]:
        """`refine`, and with `scored` the errors the loop's own kinematics give on the way (`RefineScores`): the
        given poses' position errors from its first pass, the refined poses' errors from one more pass, on the poses
        rounded to `output_dtype` as returned. A solve's checks then need no kinematics of their own.

        `until_within` (K, position tolerance, rotation tolerance): stop before a step once each target (K
        consecutive rows) has a pose within both, as every step's error already says (its parts' norms are the
        position error and the rotation angle); the scores are then those of the poses before rounding."""
        joints = rows.detach().double().numpy()
        goals = targets.detach().double().numpy()
        damping_squared = damping**2
        compiled = self.compiled() if output_dtype in (torch.float64, torch.float32) else None  # C rounds to these
        if compiled is not None:
            limits = (max_miss_fraction * self.span, np.pi / 4)
            rounded = output_dtype == torch.float32
            refined, scores = compiled.refine(
                joints, goals, steps, damping_squared, limits, until_within, scored, rounded
            )
            if not scored:
                return torch.from_numpy(refined), None
            scores = torch.from_numpy(scores)
            rotation = scores[1] if self.pose_targets else None
            return torch.from_numpy(refined), RefineScores(
                position=scores[0], rotation=rotation, first_position=scores[2]
            )
        rotations = self.target_rotations(goals) if self.pose_targets else None
        limits = np.array([max_miss_fraction * self.span, np.pi / 4])[: 2 if self.pose_targets else 1, None]
        both_goals = None
        first_position = None
        carried = None  # the kinematics of the poses a step chose, where comparing two candidates computed them
        for index in range(steps + 1):
            if index == steps:
                if not scored:
                    break
                if output_dtype != torch.float64:  # the errors of the poses as returned
                    joints = torch.from_numpy(joints).to(output_dtype).double().numpy()
                    carried = None
            if carried is None:
                frames, end = self.frames(joints)
                error = self.task_error(end, goals, rotations)
            else:
                frames, end, error = carried
                carried = None
            parts = error.reshape(len(joints), -1, 3)  # refine.clamp_task_error
            norms = norm(parts)
            if first_position is None:
                first_position = norms[:, 0, 0]
            if index == steps:
                break
            if until_within is not None and reached(norms[:, :, 0], *until_within):
                break
            jacobian = self.jacobian(joints, frames, end)
            error = (parts * (limits / np.maximum(norms, limits))).reshape(len(joints), -1)
            step = self.dls(jacobian, error, damping_squared)
            moved = self.normalized(joints + step)
            blocked = ((joints <= self.lower) & (step < 0)) | ((joints >= self.upper) & (step > 0))
            blocked &= self.limited
            if blocked.any():  # the active-set candidate, kept where it misses by less (refine.better_of)
                held = self.normalized(
                    joints + self.dls(np.where(blocked[:, None, :], 0.0, jacobian), error, damping_squared)
                )
                if both_goals is None:
                    both_goals = (
                        np.concatenate((goals, goals)),
                        None if rotations is None else np.concatenate((rotations, rotations)),
                    )
                both_frames, ends = self.frames(np.concatenate((moved, held)))
                both_errors = self.task_error(ends, *both_goals)
                misses = norm(both_errors).reshape(2, -1)
                take = blocked.any(axis=-1) & (misses[1] < misses[0])
                moved = np.where(take[:, None], held, moved)
                # the next step starts from these poses: their kinematics are here already (one pass fewer)
                count = len(joints)
                carried = (
                    np.where(take[None, :, None, None], both_frames[:, count:], both_frames[:, :count]),
                    np.where(take[:, None, None], ends[count:], ends[:count]),
                    np.where(take[:, None], both_errors[count:], both_errors[:count]),
                )
            joints = moved
        refined = torch.from_numpy(joints)
        if not scored:
            return refined, None
        # the rotation error's norm is its angle: quaternion_to_axis_angle's, as tip_and_rotation_errors measures it
        final = torch.from_numpy(norms[:, :, 0]).float()
        return refined, RefineScores(
            position=final[:, 0],
            rotation=final[:, 1] if self.pose_targets else None,
            first_position=torch.from_numpy(first_position).float(),
        )


def reached(norms: np.ndarray, per_target: int, position_tolerance: float, rotation_tolerance: float) -> bool:
    """norms (N, 1 or 2): each pose's position error (and rotation angle) -> whether every target, `per_target`
    consecutive rows, has one pose within both tolerances."""
    within = norms[:, 0] < position_tolerance
    if norms.shape[1] > 1:
        within &= norms[:, 1] < rotation_tolerance
    return bool(within.reshape(-1, per_target).any(axis=1).all())


@dataclass(frozen=True)
class RefineScores:
    """What the refinement's own kinematics measured, each (N,) float32: `ChainArm.tip_and_rotation_errors` of the
    refined poses (rotation None for position targets), and the position error of the poses it started from."""

    position: torch.Tensor
    rotation: torch.Tensor | None
    first_position: torch.Tensor

    def within(self, arm) -> torch.Tensor:
        """True where the refined pose is within the arm's tolerances, as restarts.within_tolerances says."""
        within = self.position < arm.position_tolerance
        return within if self.rotation is None else within & (self.rotation < arm.rotation_tolerance)
