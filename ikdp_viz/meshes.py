"""The planar scene's geometry, built with trimesh and sized to the arm: joint dots, the base, the target's cross.

The K arms' links are lines (scene.arm_placement); their joints and tips are these small spheres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh


@dataclass(frozen=True)
class ArmSizes:
    """Radii of the drawn arm, proportional to its mean bone length so every arm looks alike."""

    joint: float  # joint sphere radius
    tip: float  # tip sphere radius
    base: float  # base disc radius
    cross: float  # half-size of the target's cross

    @classmethod
    def for_lengths(cls, lengths) -> ArmSizes:
        mean = float(np.mean(lengths))
        return cls(joint=0.075 * mean, tip=0.085 * mean, base=0.16 * mean, cross=0.3 * mean)


def sphere_mesh(radius: float) -> trimesh.Trimesh:
    """An icosahedron, 20 faces: software WebGL pays for every triangle, K (N + 1) times a frame.

    At K = 16, N = 4 the 80-face sphere cost the playing page 8 ms a frame more (benchmarks/
    viz_frame_costs.py, 8 rounds); a dozen pixels across, the lit icosahedron reads as a dot all the same.
    """
    return trimesh.creation.icosphere(subdivisions=0, radius=radius)


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
        # flat, centred on z = 0: the scene writer lifts it over the arms and places it on the camera's ray
        # through the target (camera.over_the_point), which is exact for one height only
        bar = trimesh.creation.box(extents=(2 * half_size, width, 0.1 * width))
        bar.apply_transform(trimesh.transformations.rotation_matrix(angle, (0, 0, 1)))
        bars.append(bar)
    return trimesh.util.concatenate(bars)
