"""Planar N-link arm kinematics (paper eq. 4), batched, in plain torch.

The canonical pose is the vector of *absolute link headings* theta^n: the angle
of bone n to the +x axis. A robot's encoders read *relative joint angles*
q^n = theta^n - theta^(n-1) (q^0 = theta^0); converters go both ways.

Nothing here knows about networks or diffusion.
"""

from __future__ import annotations

import math

import torch


def wrap_angle(angle: torch.Tensor) -> torch.Tensor:
    """Wrap angles into (-pi, pi]."""
    wrapped = torch.remainder(angle + math.pi, 2 * math.pi) - math.pi  # [-pi, pi)
    return torch.where(wrapped == -math.pi, torch.full_like(wrapped, math.pi), wrapped)


def as_lengths(lengths, num_links: int, *, like: torch.Tensor) -> torch.Tensor:
    """Bone lengths as a (N,) tensor on `like`'s device and dtype; None means all ones."""
    if lengths is None:
        return torch.ones(num_links, dtype=like.dtype, device=like.device)
    lengths = torch.as_tensor(lengths, dtype=like.dtype, device=like.device)
    if lengths.shape != (num_links,):
        raise ValueError(f"lengths: expected shape ({num_links},), got {tuple(lengths.shape)}")
    return lengths


def relative_to_absolute(joint_angles: torch.Tensor) -> torch.Tensor:
    """Relative joint angles (..., N) -> absolute link headings (..., N), wrapped."""
    return wrap_angle(torch.cumsum(joint_angles, dim=-1))


def absolute_to_relative(link_headings: torch.Tensor) -> torch.Tensor:
    """Absolute link headings (..., N) -> relative joint angles (..., N), wrapped."""
    previous = torch.nn.functional.pad(link_headings[..., :-1], (1, 0))
    return wrap_angle(link_headings - previous)


def forward_kinematics(link_headings: torch.Tensor, lengths=None) -> torch.Tensor:
    """Every joint position of the arm, base first and tip last.

    link_headings: (..., N) absolute headings in radians.
    lengths: (N,) bone lengths, default all ones.
    Returns (..., N+1, 2), with the base at the origin.
    """
    link_headings = torch.as_tensor(link_headings)
    if not link_headings.is_floating_point():
        link_headings = link_headings.float()
    lengths = as_lengths(lengths, link_headings.shape[-1], like=link_headings)
    bones = torch.stack((torch.cos(link_headings), torch.sin(link_headings)), dim=-1)  # (..., N, 2)
    joints = torch.cumsum(bones * lengths[:, None], dim=-2)
    return torch.nn.functional.pad(joints, (0, 0, 1, 0))  # base at the origin


def tip_position(link_headings: torch.Tensor, lengths=None) -> torch.Tensor:
    """Tip of the arm, (..., 2): t = (sum L cos theta, sum L sin theta)."""
    link_headings = torch.as_tensor(link_headings)
    lengths = as_lengths(lengths, link_headings.shape[-1], like=link_headings)
    return torch.stack(
        ((lengths * torch.cos(link_headings)).sum(-1), (lengths * torch.sin(link_headings)).sum(-1)),
        dim=-1,
    )


def tip_jacobian(link_headings: torch.Tensor, lengths=None) -> torch.Tensor:
    """Analytic Jacobian of the tip w.r.t. the absolute headings, (..., 2, N).

    Each heading moves only its own bone: d tip / d theta^n = L^n (-sin theta^n, cos theta^n).
    """
    link_headings = torch.as_tensor(link_headings)
    lengths = as_lengths(lengths, link_headings.shape[-1], like=link_headings)
    return torch.stack((-lengths * torch.sin(link_headings), lengths * torch.cos(link_headings)), dim=-2)


def reach(lengths) -> tuple[float, float]:
    """(inner, outer) radius of the annulus the tip can reach."""
    lengths = [float(length) for length in lengths]
    outer = sum(lengths)
    inner = max(0.0, 2 * max(lengths) - outer)
    return inner, outer


def project_to_workspace(targets: torch.Tensor, lengths) -> torch.Tensor:
    """The nearest reachable point to each target (..., 2)."""
    inner, outer = reach(lengths)
    radius = targets.norm(dim=-1, keepdim=True)
    clamped = radius.clamp(min=inner, max=outer)
    along_x = torch.zeros_like(targets)  # the direction of a target at the origin; no host copy (CUDA graphs)
    along_x[..., 0].fill_(1.0)
    direction = torch.where(radius > 0, targets / radius.clamp_min(1e-12), along_x)
    return torch.where((radius < inner) | (radius > outer), direction * clamped, targets)
