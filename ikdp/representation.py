"""How a pose of J joint values becomes the vector the diffusion runs on.

`angle` is the paper's: theta / pi, one number per link, so theta = pi and
theta = -pi sit at opposite ends of the range although they are one heading.
`cossin` is wrap-free: (cos theta, sin theta) per link, 2J numbers.
`limits` is for joints with limits (a robot's): each joint scaled linearly so
its range [lower, upper] becomes [-1, 1], J numbers.
"""

from __future__ import annotations

import math

import torch

from ikdp.kinematics import wrap_angle

REPRESENTATIONS = ("angle", "cossin", "limits")


class AngleRepresentation:
    def __init__(self, kind: str, num_links: int, *, limits: torch.Tensor | None = None):
        if kind not in REPRESENTATIONS:
            raise ValueError(f"representation: expected one of {REPRESENTATIONS}, got {kind!r}")
        if kind == "limits":
            if limits is None or tuple(limits.shape) != (num_links, 2):
                got = None if limits is None else tuple(limits.shape)
                raise ValueError(f"representation 'limits': expected joint limits of shape ({num_links}, 2), got {got}")
            self.lower = limits[:, 0].float().clone()
            self.half_range = ((limits[:, 1] - limits[:, 0]) / 2).float().clone()
            self._limits_by_device: dict = {}
        self.kind = kind
        self.num_links = num_links
        self.dim = 2 * num_links if kind == "cossin" else num_links  # D, the diffused vector's size

    def encode(self, joints: torch.Tensor) -> torch.Tensor:
        """(..., J) joint values -> (..., D)."""
        if self.kind == "angle":
            return joints / math.pi
        if self.kind == "limits":
            lower, half_range = self._limits_like(joints)
            return (joints - lower) / half_range - 1
        return torch.stack((torch.cos(joints), torch.sin(joints)), dim=-1).flatten(-2)

    def decode(self, x: torch.Tensor, *, clamp: bool = True) -> torch.Tensor:
        """(..., D) -> (..., J) joint values: headings in (-pi, pi], limited joints within their limits.

        Noisy vectors decode too (a limited joint is clamped into its range, unless `clamp` is False:
        then a value past a limit decodes to the joint value past it, which forward kinematics still
        accepts and which keeps a gradient).
        """
        if self.kind == "angle":
            return wrap_angle(x * math.pi)
        if self.kind == "limits":
            lower, half_range = self._limits_like(x)
            return ((x.clamp(-1.0, 1.0) if clamp else x) + 1) * half_range + lower
        pairs = x.unflatten(-1, (self.num_links, 2))
        return torch.atan2(pairs[..., 1], pairs[..., 0])

    def _limits_like(self, like: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(lower, half_range) on `like`'s device and dtype, copied there once: a copy per call would cost a
        host-to-device transfer each step and break CUDA-graph capture."""
        key = (like.device, like.dtype)
        if key not in self._limits_by_device:
            self._limits_by_device[key] = (self.lower.to(like), self.half_range.to(like))
        return self._limits_by_device[key]

    def unit_vectors(self, x: torch.Tensor) -> torch.Tensor:
        """(..., D) -> (..., N, 2) unit direction of each bone, without an atan2 round trip."""
        if self.kind == "angle":
            return torch.stack((torch.cos(x * math.pi), torch.sin(x * math.pi)), dim=-1)
        if self.kind == "limits":
            raise ValueError("representation 'limits': joints are not headings, they have no unit vectors")
        return torch.nn.functional.normalize(x.unflatten(-1, (self.num_links, 2)), dim=-1)

    def turn(self, x: torch.Tensor, angles: torch.Tensor, *, unit: torch.Tensor | None = None) -> torch.Tensor:
        """Turn every link of x (M, D) by `angles` (M, N); `unit` = unit_vectors(x) if already known.

        Both results stay on the circle: an `angle` result wraps into (-1, 1] (theta / pi), and a
        cossin result is a unit pair, (cos, sin) times e^(i angle) as complex numbers.
        """
        if self.kind == "angle":
            return wrap_angle(x * math.pi + angles) / math.pi
        if self.kind == "limits":
            raise ValueError("representation 'limits': joints are not headings and cannot be turned")
        unit = self.unit_vectors(x) if unit is None else unit
        turned = torch.view_as_complex(unit.contiguous()) * torch.polar(torch.ones_like(angles), angles)
        return torch.view_as_real(turned).flatten(-2)

    def project(self, x: torch.Tensor) -> torch.Tensor:
        """Put an estimate of the clean sample back on the data manifold (the role of DDPM's clipping).

        A heading past pi is the same heading as one past -pi: `angle` wraps instead of clamping,
        so a link crossing the seam does not snap to it.
        """
        if self.kind == "angle":
            return wrap_angle(x * math.pi) / math.pi
        if self.kind == "limits":
            return x.clamp(-1.0, 1.0)
        return self.unit_vectors(x).flatten(-2)
