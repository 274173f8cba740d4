"""What every sampling-time constraint is: a description, and its form bound to an arm and a batch.

A constraint is a plain description (what the user asks for). `bind(arm, batch, num_samples)`
checks it against the arm (a one-line ValueError naming the problem) and spreads it over the
M = B x K sampled rows; the bound form answers what the reverse loop and the refinement ask:
- `guide(joints)`: a correction to the denoiser's clean estimate x̂0, in joint space, applied
  at every step (ikdp/guidance.py), so the whole reverse process bends toward the constraint;
- `penetration_rows(joints)`: depths and their gradients that refinement clears, second to the
  target (in its null space), so refinement keeps the constraint;
- `violation(joints)`: >= 0, zero where the constraint holds (the check and the viewer's colours).
"""

from __future__ import annotations

from typing import ClassVar

import torch

from ikdp.kinematics import wrap_angle


def joint_difference(arm, joints: torch.Tensor, reference: torch.Tensor) -> torch.Tensor:
    """joints - reference (..., J), the short way round for headings and continuous joints."""
    difference = joints - reference
    return torch.where(arm.continuous_joints.to(joints.device), wrap_angle(difference), difference)


def joint_index(arm, key) -> int:
    """A joint named by its URDF name or its 0-based index -> the index; ValueError otherwise."""
    names = list(getattr(arm, "joint_names", []))
    if isinstance(key, bool) or not isinstance(key, (int, str)):
        raise ValueError(f"locked_joints: a joint is a name or an index, got {key!r}")
    if isinstance(key, str):
        if key not in names:
            raise ValueError(f"locked_joints: unknown joint {key!r}, expected one of {names or 'indices 0..N-1'}")
        return names.index(key)
    if not 0 <= key < arm.num_joints:
        raise ValueError(f"locked_joints: joint index {key} out of range 0..{arm.num_joints - 1}")
    return key


def per_row(value: torch.Tensor, batch: int, num_samples: int, trailing: int, name: str) -> torch.Tensor:
    """One value for all targets (*S) or one per target (B, *S) -> one per sampled row (B * K, *S)."""
    if value.ndim == trailing:
        return value.expand(batch * num_samples, *value.shape)
    if value.ndim == trailing + 1 and value.shape[0] == batch:
        return value.repeat_interleave(num_samples, dim=0)
    raise ValueError(f"{name}: expected one value for all {batch} targets or one per target, got {tuple(value.shape)}")


def finite_tensor(values, name: str) -> torch.Tensor:
    try:
        tensor = torch.as_tensor(values, dtype=torch.float64)
    except (TypeError, ValueError, RuntimeError) as error:
        raise ValueError(f"{name}: expected numbers, could not read {values!r} ({error})") from None
    if not torch.isfinite(tensor).all():
        raise ValueError(f"{name}: NaN or inf in {tensor.tolist()}")
    return tensor


class Constraint:
    """A constraint as the user writes it; `bind` checks it against an arm."""

    name: ClassVar[str]

    def bind(self, arm, batch: int, num_samples: int) -> BoundConstraint:
        raise NotImplementedError


class BoundConstraint:
    """A constraint checked against an arm and spread over the M = B x K sampled rows."""

    def guide(self, joints: torch.Tensor) -> torch.Tensor | None:
        """joints (M, J) -> a correction to add (M, J), or None: no guidance."""
        return None

    def guides_at(self, fraction: float) -> bool:
        """Whether `guide` acts on the x̂0 of a step at diffusion time t = fraction * T (1: pure noise)."""
        return True

    def penetration_rows(self, joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor] | None:
        """joints (M, J) -> depths (M, P) refinement brings to zero, second to the target, their gradients (M, P, J).

        None: nothing for refinement to keep (ikdp.refine.null_space_step says how they are met).
        """
        return None

    def violation(self, joints: torch.Tensor) -> torch.Tensor:
        """joints (M, J) -> (M,) >= 0, zero where the constraint holds."""
        return torch.zeros(joints.shape[:-1], dtype=joints.dtype, device=joints.device)

    def restart_from(self, starts: torch.Tensor) -> torch.Tensor:
        """starts (R, K, J), a restart's uniform draws for its targets' rows -> the starts it refines instead."""
        return starts

    def of_rows(self, rows: torch.Tensor) -> BoundConstraint:
        """The same constraint over the sampled rows `rows` (R,) only (random restarts refine a subset)."""
        raise NotImplementedError(f"{type(self).__name__} cannot be cut to a subset of its rows")
