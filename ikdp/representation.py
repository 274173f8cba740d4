"""How a pose of J joint values becomes the vector the diffusion runs on.

`angle` is the paper's: theta / pi, one number per link, so theta = pi and
theta = -pi sit at opposite ends of the range although they are one heading.
`cossin` is wrap-free: (cos theta, sin theta) per link, 2J numbers.
`limits` is for joints with limits (a robot's): each joint scaled linearly so
its range [lower, upper] becomes [-1, 1], J numbers.
`joints` is a robot's with continuous joints too: a limited joint scaled as in
`limits`, a continuous one (no limits, e.g. a Kinova's) as its (cos, sin), so its
samples wrap around instead of being clamped at -pi and pi. On a chain without
continuous joints it is `limits`, number for number.
"""

from __future__ import annotations

import math

import torch

from ikdp.kinematics import wrap_angle

REPRESENTATIONS = ("angle", "cossin", "limits", "joints")
SCALED_BY_LIMITS = ("limits", "joints")  # the robot representations: a limited joint scaled into [-1, 1]


class AngleRepresentation:
    def __init__(
        self,
        kind: str,
        num_links: int,
        *,
        limits: torch.Tensor | None = None,
        continuous: torch.Tensor | None = None,
    ):
        """`limits` (J, 2) for the robot kinds; `continuous` (J,) bool, which joints wrap (the `joints` kind)."""
        if kind not in REPRESENTATIONS:
            raise ValueError(f"representation: expected one of {REPRESENTATIONS}, got {kind!r}")
        if kind in SCALED_BY_LIMITS:
            if limits is None or tuple(limits.shape) != (num_links, 2):
                got = None if limits is None else tuple(limits.shape)
                raise ValueError(f"representation {kind!r}: expected joint limits of shape ({num_links}, 2), got {got}")
            self.lower = limits[:, 0].float().clone()
            self.half_range = ((limits[:, 1] - limits[:, 0]) / 2).float().clone()
            self._limits_by_device: dict = {}
        wraps = torch.zeros(num_links, dtype=torch.bool)
        if kind == "joints" and continuous is not None:
            if tuple(continuous.shape) != (num_links,):
                raise ValueError(f"continuous: expected shape ({num_links},), got {tuple(continuous.shape)}")
            wraps = continuous.bool().clone()
        elif kind in ("angle", "cossin"):
            wraps = torch.ones(num_links, dtype=torch.bool)
        self.kind = kind
        self.num_links = num_links
        self._indices_by_device: dict = {}  # _on's copies
        self.wraps = wraps  # (J,) the joints whose values wrap at +-pi
        # coordinates per joint: (cos, sin) for a heading or a continuous joint, one number otherwise
        two = kind == "cossin" or (kind == "joints" and bool(wraps.any()))
        self.coordinates_per_joint = (1 + wraps.long()) if two else torch.ones(num_links, dtype=torch.long)
        self.dim = int(self.coordinates_per_joint.sum())  # D, the diffused vector's size
        if kind == "joints":
            # the first coordinate of each joint, and its second (the same one for a limited joint)
            first = torch.cumsum(self.coordinates_per_joint, 0) - self.coordinates_per_joint
            self._first, self._second = first, first + (self.coordinates_per_joint - 1)
            # encode gathers from (scaled, cos, sin) per joint: a limited joint its scaled value, a continuous one both
            picks = [[3 * j] if not bool(wraps[j]) else [3 * j + 1, 3 * j + 2] for j in range(num_links)]
            self._encode_index = torch.tensor([index for pick in picks for index in pick])

    def coordinate_mask(self, joint_mask: torch.Tensor) -> torch.Tensor:
        """(..., J) bool over joints -> (..., D) bool over the coordinates that hold those joints."""
        return joint_mask.repeat_interleave(self._on(joint_mask.device)["coordinates_per_joint"], dim=-1)

    def encode(self, joints: torch.Tensor) -> torch.Tensor:
        """(..., J) joint values -> (..., D)."""
        if self.kind == "angle":
            return joints / math.pi
        if self.kind == "limits":
            lower, half_range = self._limits_like(joints)
            return (joints - lower) / half_range - 1
        if self.kind == "joints":
            lower, half_range = self._limits_like(joints)
            choices = torch.stack(((joints - lower) / half_range - 1, torch.cos(joints), torch.sin(joints)), dim=-1)
            return choices.flatten(-2)[..., self._on(joints.device)["encode_index"]]
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
        if self.kind == "joints":
            lower, half_range = self._limits_like(x)
            indices = self._on(x.device)
            first, second = x[..., indices["first"]], x[..., indices["second"]]
            scaled = ((first.clamp(-1.0, 1.0) if clamp else first) + 1) * half_range + lower
            return torch.where(indices["wraps"], torch.atan2(second, first), scaled)
        pairs = x.unflatten(-1, (self.num_links, 2))
        return torch.atan2(pairs[..., 1], pairs[..., 0])

    def _on(self, device: torch.device) -> dict[str, torch.Tensor]:
        """The index tensors (which coordinates hold which joint) on `device`, copied there once, as the limits
        are: a host-to-device copy per call would break a CUDA graph's capture (training's or a solve's)."""
        if device not in self._indices_by_device:
            names = {"coordinates_per_joint": self.coordinates_per_joint, "wraps": self.wraps}
            if self.kind == "joints":
                names |= {"encode_index": self._encode_index, "first": self._first, "second": self._second}
            self._indices_by_device[device] = {name: value.to(device) for name, value in names.items()}
        return self._indices_by_device[device]

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
        if self.kind in SCALED_BY_LIMITS:
            raise ValueError(f"representation {self.kind!r}: joints are not headings, they have no unit vectors")
        return torch.nn.functional.normalize(x.unflatten(-1, (self.num_links, 2)), dim=-1)

    def turn(self, x: torch.Tensor, angles: torch.Tensor, *, unit: torch.Tensor | None = None) -> torch.Tensor:
        """Turn every link of x (M, D) by `angles` (M, N); `unit` = unit_vectors(x) if already known.

        Both results stay on the circle: an `angle` result wraps into (-1, 1] (theta / pi), and a
        cossin result is a unit pair, (cos, sin) times e^(i angle) as complex numbers.
        """
        if self.kind == "angle":
            return wrap_angle(x * math.pi + angles) / math.pi
        if self.kind in SCALED_BY_LIMITS:
            raise ValueError(f"representation {self.kind!r}: joints are not headings and cannot be turned")
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
        if self.kind == "joints":  # limited coordinates clamped, each continuous joint's pair back on the circle
            return self.encode(self.decode(x))
        return self.unit_vectors(x).flatten(-2)
