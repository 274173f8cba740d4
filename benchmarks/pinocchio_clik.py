"""Pinocchio (`pip install pin`, benchmarks/requirements-bench.txt) as a trusted numerical reference for a tree.

The URDF read by Pinocchio, every joint off the tree's chains locked at zero (`buildReducedModel`), so its
joints are the tree's; `forward` places the end-effector frames, and `clik` is Pinocchio's closed-loop inverse
kinematics on the stacked task of every end effector, as its documentation's example writes it: the error of
each hand is log6 of the frame's placement seen from the target's, its Jacobian the frame's LOCAL one mapped
by Jlog6, and one damped least-squares step v = -J^T (J J^T + lambda^2 I)^-1 e, integrated in full and put
back within the limits (a position model: each hand's position miss and its world-aligned linear rows). Poses
go in and out in the tree's joint order (`TreeArm.joint_names`).
"""

from __future__ import annotations

import numpy as np

DAMPING = 1e-3  # lambda, as ikdp.refine.damped_least_squares' default


class PinocchioTree:
    """A TreeArm's URDF in Pinocchio, reduced to the tree's joints."""

    def __init__(self, arm, urdf_path):
        import pinocchio as pin

        self.pin = pin
        self.version = pin.__version__
        self.position_only = arm.target == "position"  # a position model's targets: each hand's position alone
        full = pin.buildModelFromUrdf(str(urdf_path))  # fixed at the URDF's root: the base link of the tree
        root = full.frames[1].name if len(full.frames) > 1 else None
        if arm.base_link != root:
            raise ValueError(f"arm: Pinocchio's model is fixed at {root!r}, the tree at {arm.base_link!r}")
        keep = set(arm.joint_names)
        locked = [index for index in range(1, full.njoints) if full.names[index] not in keep]
        self.model = pin.buildReducedModel(full, locked, pin.neutral(full))
        self.data = self.model.createData()
        # where each of the tree's joints sits in Pinocchio's configuration vector (every joint here has one)
        self.order = [self.model.joints[self.model.getJointId(name)].idx_q for name in arm.joint_names]
        self.frames = [self.model.getFrameId(name) for name in arm.ee_links]
        self.lower, self.upper = self.model.lowerPositionLimit, self.model.upperPositionLimit

    def configuration(self, joints: np.ndarray) -> np.ndarray:
        q = np.zeros(self.model.nq)
        q[self.order] = joints
        return q

    def forward(self, joints: np.ndarray) -> list:
        """(J,) in the tree's order -> each end effector's placement (pin.SE3) in the base frame."""
        pin = self.pin
        pin.framesForwardKinematics(self.model, self.data, self.configuration(joints))
        return [self.data.oMf[frame].copy() for frame in self.frames]

    def clik(self, start: np.ndarray, goals: list, steps: int) -> np.ndarray:
        """(J,) start, goals (one pin.SE3 per end effector) -> the pose after `steps` CLIK steps, (J,)."""
        pin = self.pin
        q = self.configuration(start)
        for _ in range(steps):
            pin.computeJointJacobians(self.model, self.data, q)
            pin.updateFramePlacements(self.model, self.data)
            errors, jacobians = [], []
            for frame, goal in zip(self.frames, goals, strict=True):
                if self.position_only:  # the hand's position alone: its miss and the world-aligned linear rows
                    errors.append(self.data.oMf[frame].translation - goal.translation)
                    aligned = pin.getFrameJacobian(self.model, self.data, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
                    jacobians.append(aligned[:3])
                    continue
                seen = goal.actInv(self.data.oMf[frame])  # the hand in the target's frame
                errors.append(pin.log6(seen).vector)
                local = pin.getFrameJacobian(self.model, self.data, frame, pin.ReferenceFrame.LOCAL)
                jacobians.append(pin.Jlog6(seen) @ local)
            error, jacobian = np.concatenate(errors), np.concatenate(jacobians)
            gram = jacobian @ jacobian.T + DAMPING**2 * np.eye(len(error))
            velocity = -jacobian.T @ np.linalg.solve(gram, error)
            q = np.clip(pin.integrate(self.model, q, velocity), self.lower, self.upper)
        return q[self.order]
