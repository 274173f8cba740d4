"""How a pose of N link headings becomes the vector the diffusion runs on.

`angle` is the paper's: theta / pi, one number per link, so theta = pi and
theta = -pi sit at opposite ends of the range although they are one heading.
`cossin` is wrap-free: (cos theta, sin theta) per link, 2N numbers.
"""

from __future__ import annotations

import math

import torch

from ikdp.kinematics import wrap_angle

REPRESENTATIONS = ("angle", "cossin")


class AngleRepresentation:
    def __init__(self, kind: str, num_links: int):
        if kind not in REPRESENTATIONS:
            raise ValueError(f"representation: expected one of {REPRESENTATIONS}, got {kind!r}")
        self.kind = kind
        self.num_links = num_links
        self.dim = num_links if kind == "angle" else 2 * num_links  # D, the diffused vector's size

    def encode(self, link_headings: torch.Tensor) -> torch.Tensor:
        """(..., N) headings -> (..., D)."""
        if self.kind == "angle":
            return link_headings / math.pi
        return torch.stack((torch.cos(link_headings), torch.sin(link_headings)), dim=-1).flatten(-2)

    def decode(self, x: torch.Tensor) -> torch.Tensor:
        """(..., D) -> (..., N) headings in (-pi, pi]; noisy vectors decode too."""
        if self.kind == "angle":
            return wrap_angle(x * math.pi)
        pairs = x.unflatten(-1, (self.num_links, 2))
        return torch.atan2(pairs[..., 1], pairs[..., 0])

    def unit_vectors(self, x: torch.Tensor) -> torch.Tensor:
        """(..., D) -> (..., N, 2) unit direction of each bone, without an atan2 round trip."""
        if self.kind == "angle":
            return torch.stack((torch.cos(x * math.pi), torch.sin(x * math.pi)), dim=-1)
        return torch.nn.functional.normalize(x.unflatten(-1, (self.num_links, 2)), dim=-1)

    def turn(self, x: torch.Tensor, angles: torch.Tensor, *, unit: torch.Tensor | None = None) -> torch.Tensor:
        """Turn every link of x (M, D) by `angles` (M, N); `unit` = unit_vectors(x) if already known.

        cossin results are unit pairs: (cos, sin) times e^(i angle), as complex numbers.
        """
        if self.kind == "angle":
            return x + angles / math.pi
        unit = self.unit_vectors(x) if unit is None else unit
        turned = torch.view_as_complex(unit.contiguous()) * torch.polar(torch.ones_like(angles), angles)
        return torch.view_as_real(turned).flatten(-2)

    def project(self, x: torch.Tensor) -> torch.Tensor:
        """Put an estimate of the clean sample back on the data manifold (the role of DDPM's clipping)."""
        if self.kind == "angle":
            return x.clamp(-1.0, 1.0)
        return self.unit_vectors(x).flatten(-2)
