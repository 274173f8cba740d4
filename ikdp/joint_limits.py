"""Joint limits as a robot arm applies them: clamp or wrap, a step blocked at a limit, joints outside.

One piece for a chain (chain_arm.py) and a tree of chains (tree_arm.py): both keep their limits (J, 2) and which
joints are continuous (J,) in `_constants_like(joints)`, copied to the joints' device and dtype once.
"""

from __future__ import annotations

import torch

from ikdp.kinematics import wrap_angle


class JointLimits:
    """Mixin: the limit rules of an arm whose `_constants_like(joints)` gives "limits" (J, 2) and "continuous" (J,)."""

    def normalize_joints(self, joints: torch.Tensor) -> torch.Tensor:
        """Back into range after a step: limited joints clamp to their limits, continuous ones wrap into (-pi, pi]."""
        c = self._constants_like(joints)
        clamped = torch.minimum(torch.maximum(joints, c["limits"][:, 0]), c["limits"][:, 1])
        return torch.where(c["continuous"], wrap_angle(joints), clamped)

    def blocked_by_limits(self, joints: torch.Tensor, step: torch.Tensor) -> torch.Tensor:
        """(..., J) joints, a proposed step -> (..., J) True where a joint on a limit is pushed further out."""
        c = self._constants_like(joints)
        pushed_out = ((joints <= c["limits"][:, 0]) & (step < 0)) | ((joints >= c["limits"][:, 1]) & (step > 0))
        return pushed_out & ~c["continuous"]

    def limit_violations(self, joints: torch.Tensor, *, tolerance: float = 1e-6) -> torch.Tensor:
        """(..., J) -> (...) how many joints lie outside their limits (continuous joints never do)."""
        c = self._constants_like(joints)
        outside = (joints < c["limits"][:, 0] - tolerance) | (joints > c["limits"][:, 1] + tolerance)
        return (outside & ~c["continuous"]).sum(dim=-1)
