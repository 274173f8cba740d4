"""A robot's links as a few spheres each, fitted once to its collision meshes and stored.

Collision checks against obstacles and the gradient of the penetration depth need a shape
that is cheap and smooth to move: spheres fixed in the link frames. Each link's collision
geometry (meshes read with trimesh, or URDF boxes, cylinders and spheres) is split into a
few clusters of points, each covered by the smallest sphere around it, so the spheres contain
every vertex and sampled surface point: a conservative cover.

Fitting needs trimesh (the `[viz]` extra) and the URDF's meshes, so the result is stored:
in memory per arm, in `ikdp/collision_spheres/` for the shipped robots (the Panda's is in
the package, so the core install has it), and in ikdp's cache folder for any other arm.
The file is named after a hash of the arm's kinematics, so a changed URDF is fitted anew.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

SHIPPED_FOLDER = Path(__file__).resolve().parent / "collision_spheres"
MAX_SPHERES_PER_LINK = 4  # more spheres fit a link tighter; each one costs every collision check
WORTHWHILE_SHRINK = 0.9  # a split is kept only if its larger half's sphere is at most this share of the one it splits
SURFACE_SAMPLES = 2000  # points sampled on each mesh's surface besides its vertices: the cover is checked on them


@dataclass(frozen=True)
class LinkSpheres:
    """S spheres, each fixed in one link's frame."""

    link_indices: tuple[int, ...]  # (S,) each sphere's link, an index into arm.link_names
    centers: tuple[tuple[float, float, float], ...]  # (S, 3) in that link's frame, metres
    radii: tuple[float, ...]  # (S,) metres

    def __len__(self) -> int:
        return len(self.radii)

    def world_centers(self, arm, joints: torch.Tensor) -> torch.Tensor:
        """joints (..., J) -> the sphere centres in the base frame, (..., S, 3)."""
        poses = arm.link_poses(joints)[..., list(self.link_indices), :, :]  # (..., S, 4, 4)
        centers = torch.tensor(self.centers, dtype=joints.dtype, device=joints.device)
        return (poses[..., :3, :3] @ centers[..., None])[..., 0] + poses[..., :3, 3]

    def radii_like(self, like: torch.Tensor) -> torch.Tensor:
        return torch.tensor(self.radii, dtype=like.dtype, device=like.device)

    def to_dict(self) -> dict:
        return {
            "link_indices": list(self.link_indices),
            "centers": [list(c) for c in self.centers],
            "radii": list(self.radii),
        }

    @classmethod
    def from_dict(cls, values: dict) -> LinkSpheres:
        return cls(
            link_indices=tuple(int(index) for index in values["link_indices"]),
            centers=tuple(tuple(float(x) for x in center) for center in values["centers"]),
            radii=tuple(float(radius) for radius in values["radii"]),
        )


_memory: dict[str, LinkSpheres] = {}


def arm_key(arm) -> str:
    """A short hash of what places the links: the kinematics and link names, not the file's path."""
    config = {key: value for key, value in arm.to_config().items() if key not in ("urdf_path", "target")}
    return hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:16]


def user_cache_folder() -> Path:
    from ikdp.denoisers.film_compiled import cache_folder

    return cache_folder() / "link_spheres"


def link_spheres(arm) -> LinkSpheres:
    """The arm's link spheres: stored ones when there are, else fitted now (trimesh) and stored."""
    key = arm_key(arm)
    if key in _memory:
        return _memory[key]
    for folder in (SHIPPED_FOLDER, user_cache_folder()):
        path = folder / f"{key}.json"
        if path.is_file():
            _memory[key] = LinkSpheres.from_dict(json.loads(path.read_text())["spheres"])
            return _memory[key]
    spheres = fit_link_spheres(arm)
    store(arm, spheres, user_cache_folder())
    _memory[key] = spheres
    return spheres


def store(arm, spheres: LinkSpheres, folder: Path) -> Path:
    """Write the spheres as JSON named after the arm's key; atomic, so a reader never sees half a file."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{arm_key(arm)}.json"
    payload = {"links": list(arm.link_names), "ee_link": arm.ee_link, "spheres": spheres.to_dict()}
    partial = path.with_suffix(".json.part")
    partial.write_text(json.dumps(payload, indent=1))
    partial.replace(path)
    return path


def fit_link_spheres(arm, *, max_per_link: int = MAX_SPHERES_PER_LINK) -> LinkSpheres:
    """Fit spheres to each link's collision geometry (trimesh); ValueError when it cannot be read."""
    try:
        import trimesh
    except ImportError:
        raise ValueError("obstacles: fitting the links' spheres needs trimesh (pip install 'ikdp[viz]')") from None
    description = arm.chain_description()
    if description is None:
        raise ValueError(f"obstacles: no URDF found for {arm!r}, so its collision meshes cannot be read")
    generator = np.random.default_rng(0)
    indices, centers, radii = [], [], []
    for link_index, link in enumerate(description.links):
        points = [geometry_points(trimesh, geometry, generator) for geometry in link.collisions]
        points = [chunk for chunk in points if chunk is not None]
        if not points:
            continue
        for center, radius in cover_with_spheres(np.concatenate(points), max_per_link):
            indices.append(link_index)
            centers.append(tuple(float(x) for x in center))
            radii.append(float(radius))
    if not radii:
        raise ValueError(f"obstacles: {arm!r} has no readable collision geometry")
    return LinkSpheres(tuple(indices), tuple(centers), tuple(radii))


def geometry_points(trimesh, geometry, generator: np.random.Generator) -> np.ndarray | None:
    """A collision element's vertices and surface samples, (P, 3), in its link's frame."""
    if geometry.kind == "mesh":
        if geometry.path is None:
            return None
        mesh = trimesh.load(geometry.path, force="mesh")
        mesh.apply_scale(geometry.scale)
    elif geometry.kind == "box":
        mesh = trimesh.creation.box(extents=geometry.size)
    elif geometry.kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=geometry.size[0], height=geometry.size[1])
    elif geometry.kind == "sphere":
        mesh = trimesh.creation.icosphere(radius=geometry.size[0])
    else:
        return None
    seed = int(generator.integers(2**31))
    surface, _ = trimesh.sample.sample_surface(mesh, SURFACE_SAMPLES, seed=seed)
    points = np.concatenate([np.asarray(mesh.vertices), np.asarray(surface)])
    from ikdp.rotations import rpy_to_matrix

    rotation = rpy_to_matrix(torch.tensor(geometry.origin.rpy, dtype=torch.float64)).numpy()
    return points @ rotation.T + np.asarray(geometry.origin.xyz)


def cover_with_spheres(points: np.ndarray, max_spheres: int) -> list[tuple[np.ndarray, float]]:
    """Spheres containing every point (P, 3): the largest sphere's points split in two until no split pays.

    Each split is 2-means started across the points' principal axis, and each part gets its
    smallest enclosing sphere. Splitting stops at `max_spheres`, or when halving the largest
    sphere would shrink it by less than `WORTHWHILE_SHRINK` (the Panda's arm links stop at 2, the
    base, wrist and hand go on to 4). The Panda's cover sticks out 1.2 to 2.8 cm beyond its meshes
    (median per link) with 26 spheres of 4.5 to 9.6 cm, against 1.5 to 4.4 cm with 20 spheres of
    5.4 to 12.4 cm for one sphere per slab along the link's axis, the fit before.
    """
    clusters, spheres = [points], [enclosing_sphere(points)]
    while len(spheres) < max_spheres:
        largest = max(range(len(spheres)), key=lambda index: spheres[index][1])
        halves = split_in_two(clusters[largest])
        if halves is None:
            break
        covers = [enclosing_sphere(half) for half in halves]
        if max(radius for _, radius in covers) > WORTHWHILE_SHRINK * spheres[largest][1]:
            break
        clusters[largest : largest + 1], spheres[largest : largest + 1] = halves, covers
    return spheres


def split_in_two(points: np.ndarray, iterations: int = 20) -> list[np.ndarray] | None:
    """2-means of the points (P, 3), started by the sign along their principal axis; None if they cannot split."""
    mean = points.mean(axis=0)
    _, _, axes = np.linalg.svd(points - mean, full_matrices=False)
    second = (points - mean) @ axes[0] > 0
    for _ in range(iterations):
        if second.all() or not second.any():
            return None
        first_center, second_center = points[~second].mean(axis=0), points[second].mean(axis=0)
        nearer_second = ((points - second_center) ** 2).sum(1) < ((points - first_center) ** 2).sum(1)
        if (nearer_second == second).all():
            break
        second = nearer_second
    return [points[~second], points[second]]


def enclosing_sphere(points: np.ndarray, iterations: int = 200) -> tuple[np.ndarray, float]:
    """A near-smallest sphere around the points (Badoiu and Clarkson 2003: step toward the farthest point)."""
    center = (points.max(axis=0) + points.min(axis=0)) / 2
    for iteration in range(iterations):
        farthest = points[np.argmax(((points - center) ** 2).sum(axis=1))]
        center = center + (farthest - center) / (iteration + 2)
    return center, float(np.sqrt(((points - center) ** 2).sum(axis=1).max()))  # every point inside, exactly
