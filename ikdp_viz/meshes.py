"""The arm's geometry, built with trimesh and sized to the arm: links, joints, tip, base, the target's cross.

Links are a unit-length cylinder along +x, centred on the origin, that the viewer
scales along x to each bone; with a sphere on every joint they read as capsules.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh


@dataclass(frozen=True)
class ArmSizes:
    """Radii of the drawn arm, proportional to its mean bone length so every arm looks alike."""

    link: float  # link cylinder radius
    joint: float  # joint sphere radius
    tip: float  # tip marker radius
    base: float  # base disc radius
    cross: float  # half-size of the target's cross

    @classmethod
    def for_lengths(cls, lengths) -> ArmSizes:
        mean = float(np.mean(lengths))
        return cls(link=0.045 * mean, joint=0.075 * mean, tip=0.085 * mean, base=0.16 * mean, cross=0.3 * mean)


def link_mesh(radius: float) -> trimesh.Trimesh:
    """Cylinder of unit length along +x, centred on the origin."""
    cylinder = trimesh.creation.cylinder(radius=radius, height=1.0, sections=16)  # along z
    cylinder.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    return cylinder


def sphere_mesh(radius: float, subdivisions: int = 2) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def base_mesh(radius: float) -> trimesh.Trimesh:
    """A flat disc under the first joint, below the plane so the arm draws over it."""
    disc = trimesh.creation.cylinder(radius=radius, height=0.25 * radius, sections=32)
    disc.apply_translation((0.0, 0.0, -0.25 * radius))
    return disc


def cross_mesh(half_size: float, width: float | None = None) -> trimesh.Trimesh:
    """The paper's red cross marking the target: two thin bars crossing at 45 degrees."""
    width = width if width is not None else 0.22 * half_size
    bars = []
    for angle in (np.pi / 4, -np.pi / 4):
        bar = trimesh.creation.box(extents=(2 * half_size, width, width))
        bar.apply_transform(trimesh.transformations.rotation_matrix(angle, (0, 0, 1)))
        bars.append(bar)
    cross = trimesh.util.concatenate(bars)
    cross.apply_translation((0.0, 0.0, 2 * width))  # above the arm, so the target is never hidden
    return cross
