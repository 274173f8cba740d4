"""Distributions of poses the model learns to sample from.

A prior draws absolute link headings (n, N). `uniform` is the paper's: every
heading uniform on (-pi, pi]. `relaxed` keeps the base heading uniform and draws
every relative joint angle from N(0, relaxed_std^2), so bent-back poses are rare.
`file` resamples poses the user supplied (relative joint angles, one per row).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ikdp.arm import uniform_angles
from ikdp.arm_inputs import drawing_device
from ikdp.kinematics import relative_to_absolute

PRIOR_KINDS = ("uniform", "relaxed", "file")


@dataclass(frozen=True)
class PosePrior:
    kind: str = "uniform"
    relaxed_std: float = math.pi / 4  # std of each relative joint angle for `relaxed`
    poses: torch.Tensor | None = None  # (P, N) relative joint angles for `file`
    source: str = ""  # where `file` poses came from
    _copies: dict = field(default_factory=dict, init=False, repr=False, compare=False)  # poses_on's, per device

    def __post_init__(self):
        if self.kind not in PRIOR_KINDS:
            raise ValueError(f"prior: expected one of {PRIOR_KINDS}, got {self.kind!r}")
        if self.kind == "file" and self.poses is None:
            raise ValueError("prior: kind 'file' needs poses")

    def sample(self, count: int, arm, *, generator: torch.Generator | None = None) -> torch.Tensor:
        """Draw `count` poses, (count, J). `arm`: an arm, or the number of links of a planar one.

        `uniform` is the arm's own draw (every heading on the circle, or every joint within its
        limits); `relaxed` and `file` are planar: absolute link headings.
        """
        if not isinstance(arm, int):
            if self.kind == "uniform":
                return arm.random_poses(count, generator=generator)
            if arm.kind != "planar":
                raise ValueError(f"prior {self.kind!r}: defined for planar arms only, got a {arm.kind} arm")
            arm = arm.num_joints
        num_links = arm
        device = drawing_device(generator)  # a training's data is drawn on its GPU: nothing copied per batch
        if self.kind == "uniform":
            return uniform_angles((count, num_links), generator=generator, device=device)
        if self.kind == "relaxed":
            base = uniform_angles((count, 1), generator=generator, device=device)
            bends = torch.randn(count, num_links - 1, generator=generator, device=device) * self.relaxed_std
            return relative_to_absolute(torch.cat((base, bends), dim=-1))
        if self.poses.shape[1] != num_links:
            raise ValueError(f"prior: file poses have {self.poses.shape[1]} joints, the arm has {num_links}")
        rows = torch.randint(len(self.poses), (count,), generator=generator, device=device)
        return relative_to_absolute(self.poses_on(device)[rows])

    def poses_on(self, device: torch.device) -> torch.Tensor:
        """The file's poses on `device`, copied there once."""
        if device not in self._copies:
            self._copies[device] = self.poses.to(device)
        return self._copies[device]

    def to_config(self) -> dict:
        """Plain values and tensors only, for a checkpoint."""
        config = {"kind": self.kind, "relaxed_std": self.relaxed_std, "source": self.source}
        if self.poses is not None:
            config["poses"] = self.poses.clone()
        return config

    @classmethod
    def from_config(cls, config: dict) -> PosePrior:
        return cls(
            kind=config["kind"],
            relaxed_std=float(config.get("relaxed_std", math.pi / 4)),
            poses=config.get("poses"),
            source=config.get("source", ""),
        )


def load_pose_file(path: str | Path, num_links: int) -> torch.Tensor:
    """Read user poses from .npy or .csv: one pose per row, relative joint angles in radians."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"prior file {path}: no such file")
    try:
        if path.suffix == ".npy":
            poses = np.load(path, allow_pickle=False)
        elif path.suffix == ".csv":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # an empty file is reported below, as a ValueError
                poses = np.loadtxt(path, delimiter=",", ndmin=2)
        else:
            raise ValueError(f"prior file {path}: expected a .npy or .csv file")
    except ValueError as error:
        if str(error).startswith("prior file"):
            raise
        raise ValueError(f"prior file {path}: cannot read it ({error})") from None
    poses = np.asarray(poses, dtype=np.float64)
    if poses.size == 0:
        raise ValueError(f"prior file {path}: it holds no poses")
    if poses.ndim == 1:
        poses = poses[None]
    if poses.ndim != 2 or poses.shape[1] != num_links:
        raise ValueError(f"prior file {path}: expected {num_links} joint angles per row, got shape {poses.shape}")
    bad_rows = np.flatnonzero(~np.isfinite(poses).all(axis=1))
    if len(bad_rows):
        raise ValueError(f"prior file {path}: row {bad_rows[0]} holds NaN or inf")
    return torch.from_numpy(poses).float()


def make_prior(
    kind: str, num_links: int, *, pose_file: str | None = None, relaxed_std: float = math.pi / 4
) -> PosePrior:
    """Build a prior from a CLI word: uniform, relaxed, or a path to a pose file."""
    if kind in ("uniform", "relaxed"):
        return PosePrior(kind=kind, relaxed_std=relaxed_std)
    path = pose_file or kind
    return PosePrior(kind="file", poses=load_pose_file(path, num_links), source=str(path))
