"""A robot's links as a few spheres each, fitted once to its collision meshes and stored.

Collision checks against obstacles and the gradient of the penetration depth need a shape
that is cheap and smooth to move: spheres fixed in the link frames. Each link's collision
geometry (meshes read with trimesh, or URDF boxes, cylinders and spheres) is cut into small
triangles, the triangles are split into a few clusters, and each cluster is covered by the
smallest sphere around its triangles' corners. A sphere is convex, so it holds every point of
those triangles: the spheres cover the whole surface, not only the vertices or some samples of it.

Every link that moves with the chain is covered: the chain's links (fixed ones included) and the
links that hang off them (a gripper's fingers, ikdp/urdf.py's `hanging`). A hanging link's spheres
are stored in its own frame with the joints that place it, so its joints can be held at any value
without fitting again: by default each at the end of its range farthest from zero (the Panda's
fingers open, 4 cm each; the Z1's gripper open), or at `held_joints` given (`ikdp.Obstacles`).

Fitting needs trimesh (the `[viz]` extra) and the URDF's meshes, so the result is stored:
in memory per arm, in `ikdp/collision_spheres/` for the shipped robots (in the package, so the
core install has them; `python -m ikdp.fit_link_spheres panda z1` fits them again), and in ikdp's
cache folder for any other arm. The file is named after a hash of the arm's kinematics and the
fitting rule's version, so a changed URDF (or rule) is fitted anew.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

SHIPPED_FOLDER = Path(__file__).resolve().parent / "collision_spheres"
FIT_VERSION = 2  # the fitting rule, part of the stored file's name: 1 covered vertices and samples, 2 every triangle
MAX_SPHERES_PER_LINK = 4  # more spheres fit a link tighter; each one costs every collision check
WORTHWHILE_SHRINK = 0.9  # a split is kept only if its larger half's sphere is at most this share of the one it splits
MAX_EDGE = 0.01  # metres: meshes are cut into triangles no longer than this, so clusters can follow the surface
CYLINDER_SECTIONS = 32  # a URDF cylinder as a prism with this many flat sides, drawn around (outside) it
PLACING_FIELDS = (  # what places the links: an arm's key hashes these (not its limits, file path or target)
    "joint_names",
    "joint_types",
    "joint_offsets",
    "joint_axes",
    "ee_offset",
    "link_names",
    "link_frames",
    "link_offsets",
    "base_link",
    "ee_link",
)


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


@dataclass(frozen=True)
class HeldJoint:
    """A joint off the chain, between a chain link and a hanging link: never moved by IK, held at a value."""

    name: str
    type: str  # revolute, continuous, prismatic or fixed (a floating or planar joint is read as fixed)
    origin: tuple[tuple[float, ...], ...]  # (4, 4) its frame at value zero in its parent link's frame
    axis: tuple[float, float, float]  # unit axis in that frame
    lower: float | None  # limits, None where the URDF gives none
    upper: float | None
    mimic: tuple[str, float, float] | None = None  # (joint it follows, multiplier, offset): value = m * that + o

    @classmethod
    def of(cls, joint) -> HeldJoint:
        """From a parsed JointDescription (ikdp/urdf.py)."""
        from ikdp.rotations import origin_matrix

        return cls(
            joint.name,
            joint.type,
            tuple(tuple(row) for row in origin_matrix(joint.origin)),
            tuple(joint.axis),
            joint.lower,
            joint.upper,
            joint.mimic,
        )

    @property
    def movable(self) -> bool:
        return self.type != "fixed"

    @property
    def default_value(self) -> float:
        """The end of its range farthest from zero (a gripper open, for the Panda and the Z1); 0 without limits."""
        if self.lower is None or self.upper is None:
            return 0.0
        return self.upper if abs(self.upper) >= abs(self.lower) else self.lower

    def transform(self, value: float) -> np.ndarray:
        """(4, 4) the child link's frame in the parent link's frame, the joint at `value`."""
        motion = np.eye(4)
        axis = np.asarray(self.axis)
        if self.type == "prismatic":
            motion[:3, 3] = axis * value
        elif self.type in ("revolute", "continuous"):  # Rodrigues
            cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
            motion[:3, :3] = np.eye(3) + math.sin(value) * cross + (1 - math.cos(value)) * cross @ cross
        return np.asarray(self.origin) @ motion

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "type": self.type,
            "origin": [list(row) for row in self.origin],
            "axis": list(self.axis),
            "lower": self.lower,
            "upper": self.upper,
            "mimic": None if self.mimic is None else list(self.mimic),
        }

    @classmethod
    def from_dict(cls, values: dict) -> HeldJoint:
        mimic = values.get("mimic")
        return cls(
            name=values["name"],
            type=values["type"],
            origin=tuple(tuple(float(x) for x in row) for row in values["origin"]),
            axis=tuple(float(x) for x in values["axis"]),
            lower=values["lower"],
            upper=values["upper"],
            mimic=None if mimic is None else (str(mimic[0]), float(mimic[1]), float(mimic[2])),
        )


@dataclass(frozen=True)
class HangingSpheres:
    """A link off the chain (a gripper's finger): its spheres in its own frame, and the joints that place it."""

    link: str  # its name in the URDF
    parent: int  # the chain link it hangs from, an index into arm.link_names
    joints: tuple[HeldJoint, ...]  # from that chain link down to it
    centers: tuple[tuple[float, float, float], ...]  # (S, 3) in its own frame, metres
    radii: tuple[float, ...]  # (S,)

    def to_dict(self) -> dict:
        return {
            "link": self.link,
            "parent": self.parent,
            "joints": [joint.to_dict() for joint in self.joints],
            "centers": [list(c) for c in self.centers],
            "radii": list(self.radii),
        }

    @classmethod
    def from_dict(cls, values: dict) -> HangingSpheres:
        return cls(
            link=values["link"],
            parent=int(values["parent"]),
            joints=tuple(HeldJoint.from_dict(joint) for joint in values["joints"]),
            centers=tuple(tuple(float(x) for x in center) for center in values["centers"]),
            radii=tuple(float(radius) for radius in values["radii"]),
        )


@dataclass(frozen=True)
class SphereCover:
    """Everything that moves with an arm's chain as spheres: the chain's links, and the links hanging off them."""

    chain: LinkSpheres  # in the chain links' frames
    hanging: tuple[HangingSpheres, ...] = ()  # each in its own frame

    @property
    def held_joints(self) -> dict[str, HeldJoint]:
        """The movable joints off the chain, by name: what `held_joints` may set."""
        return {joint.name: joint for item in self.hanging for joint in item.joints if joint.movable}

    def held_values(self, held_joints: Mapping | None = None) -> dict[str, float]:
        """Every movable joint off the chain -> its value: as given, else its default; a mimic joint follows."""
        joints, given = self.held_joints, dict(held_joints or {})
        for name, value in given.items():
            if name not in joints:
                known = ", ".join(sorted(joints)) or "none"
                raise ValueError(f"held_joints: no joint {name!r} off the chain (its joints there: {known})")
            joint = joints[name]
            if joint.mimic is not None:
                raise ValueError(f"held_joints: joint {name!r} follows {joint.mimic[0]!r} (mimic): give that one")
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
                raise ValueError(f"held_joints: joint {name!r} expected a finite number, got {value!r}")
            if joint.lower is not None and not joint.lower <= value <= joint.upper:
                raise ValueError(
                    f"held_joints: joint {name!r} value {value:.6g} outside its limits [{joint.lower}, {joint.upper}]"
                )
        values = {
            name: float(given.get(name, joint.default_value)) for name, joint in joints.items() if not joint.mimic
        }
        for name, joint in joints.items():
            if joint.mimic is not None:
                leader, multiplier, offset = joint.mimic
                # one that follows a chain joint cannot be held still: it stays at its default
                values[name] = multiplier * values[leader] + offset if leader in values else joint.default_value
        return values

    def posed(self, held_joints: Mapping | None = None) -> LinkSpheres:
        """Every sphere in its chain link's frame, the joints off the chain held at `held_values(held_joints)`."""
        values = self.held_values(held_joints)
        indices, centers, radii = list(self.chain.link_indices), list(self.chain.centers), list(self.chain.radii)
        for item in self.hanging:
            frame = np.eye(4)  # the hanging link in its chain link's frame
            for joint in item.joints:
                frame = frame @ joint.transform(values.get(joint.name, 0.0))
            for center, radius in zip(item.centers, item.radii, strict=True):
                indices.append(item.parent)
                centers.append(tuple(float(x) for x in frame[:3, :3] @ np.asarray(center) + frame[:3, 3]))
                radii.append(radius)
        return LinkSpheres(tuple(indices), tuple(centers), tuple(radii))

    def to_dict(self) -> dict:
        return {**self.chain.to_dict(), "hanging": [item.to_dict() for item in self.hanging]}

    @classmethod
    def from_dict(cls, values: dict) -> SphereCover:
        return cls(LinkSpheres.from_dict(values), tuple(HangingSpheres.from_dict(item) for item in values["hanging"]))


_memory: dict[str, SphereCover] = {}


def arm_key(arm) -> str:
    """A short hash of what places the links (the kinematics and link names, not the file's path) and of the
    fitting rule. The links hanging off the chain are not in it: an arm from a checkpoint knows only its chain."""
    config = arm.to_config()
    placing = {name: config[name] for name in PLACING_FIELDS}
    text = json.dumps({"arm": placing, "fit": FIT_VERSION}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def user_cache_folder() -> Path:
    from ikdp.denoisers.film_compiled import cache_folder

    return cache_folder() / "link_spheres"


def sphere_cover(arm) -> SphereCover:
    """The arm's cover: stored when it is, else fitted now (trimesh) and stored in the user's cache."""
    key = arm_key(arm)
    if key in _memory:
        return _memory[key]
    for folder in (SHIPPED_FOLDER, user_cache_folder()):
        path = folder / f"{key}.json"
        if path.is_file():
            _memory[key] = SphereCover.from_dict(json.loads(path.read_text())["spheres"])
            return _memory[key]
    cover = fit_sphere_cover(arm)
    store(arm, cover, user_cache_folder())
    _memory[key] = cover
    return cover


def link_spheres(arm, held_joints: Mapping | None = None) -> LinkSpheres:
    """Every sphere of the arm in its chain link's frame; the joints off the chain (fingers) held at `held_joints`
    (name -> value), the others at their default (SphereCover.held_values)."""
    return sphere_cover(arm).posed(held_joints)


def store(arm, cover: SphereCover, folder: Path) -> Path:
    """Write the cover as JSON named after the arm's key; atomic, so a reader never sees half a file."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{arm_key(arm)}.json"
    payload = {
        "links": list(arm.link_names),
        "ee_link": arm.ee_link,
        "fit": {"version": FIT_VERSION, "max_per_link": MAX_SPHERES_PER_LINK, "max_edge_m": MAX_EDGE},
        "spheres": cover.to_dict(),
    }
    partial = path.with_suffix(".json.part")
    partial.write_text(json.dumps(payload, indent=1))
    partial.replace(path)
    return path


def fit_sphere_cover(arm, *, max_per_link: int = MAX_SPHERES_PER_LINK) -> SphereCover:
    """Fit spheres to the collision geometry of every link on and off the chain (trimesh); ValueError when it
    cannot be read."""
    try:
        import trimesh
    except ImportError:
        raise ValueError("obstacles: fitting the links' spheres needs trimesh (pip install 'ikdp[viz]')") from None
    description = arm.chain_description()
    if description is None:
        raise ValueError(f"obstacles: no URDF found for {arm!r}, so its collision meshes cannot be read")

    def covered(link) -> list[tuple[np.ndarray, float]]:
        triangles = [geometry_triangles(trimesh, geometry) for geometry in link.collisions]
        triangles = [chunk for chunk in triangles if chunk is not None]
        return cover_with_spheres(np.concatenate(triangles), max_per_link) if triangles else []

    indices, centers, radii = [], [], []
    for link_index, link in enumerate(description.links):
        for center, radius in covered(link):
            indices.append(link_index)
            centers.append(tuple(float(x) for x in center))
            radii.append(radius)
    hanging = []
    for item in description.hanging:
        spheres = covered(item.link)
        if spheres:
            hanging.append(
                HangingSpheres(
                    link=item.link.name,
                    parent=item.parent,
                    joints=tuple(HeldJoint.of(joint) for joint in item.joints),
                    centers=tuple(tuple(float(x) for x in center) for center, _ in spheres),
                    radii=tuple(radius for _, radius in spheres),
                )
            )
    if not radii and not hanging:
        raise ValueError(f"obstacles: {arm!r} has no readable collision geometry")
    return SphereCover(LinkSpheres(tuple(indices), tuple(centers), tuple(radii)), tuple(hanging))


def geometry_triangles(trimesh, geometry) -> np.ndarray | None:
    """A collision element's surface as triangles no longer than MAX_EDGE, (F, 3 corners, 3), in its link's frame.

    A mesh as it is; a box exactly; a cylinder and a sphere as polyhedra around them (their flat
    faces outside the round surface), so that covering the triangles covers the shape.
    """
    if geometry.kind == "mesh":
        if geometry.path is None:
            return None
        mesh = trimesh.load(geometry.path, force="mesh")
        mesh.apply_scale(geometry.scale)
    elif geometry.kind == "box":
        mesh = trimesh.creation.box(extents=geometry.size)
    elif geometry.kind == "cylinder":
        radius, length = geometry.size
        circumscribed = radius / math.cos(math.pi / CYLINDER_SECTIONS)  # each flat side touches the cylinder
        mesh = trimesh.creation.cylinder(radius=circumscribed, height=length, sections=CYLINDER_SECTIONS)
    elif geometry.kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        nearest_face = float(np.abs((mesh.face_normals * mesh.triangles_center).sum(axis=1)).min())
        mesh.apply_scale(geometry.size[0] / nearest_face)  # every face at least the radius from the centre
    else:
        return None
    if len(mesh.faces) == 0:
        return None
    vertices, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, MAX_EDGE, max_iter=20)
    from ikdp.rotations import rpy_to_matrix

    rotation = rpy_to_matrix(torch.tensor(geometry.origin.rpy, dtype=torch.float64)).numpy()
    return np.asarray(vertices)[np.asarray(faces)] @ rotation.T + np.asarray(geometry.origin.xyz)


def cover_with_spheres(triangles: np.ndarray, max_spheres: int) -> list[tuple[np.ndarray, float]]:
    """Spheres holding every triangle (F, 3, 3) whole: the largest sphere's triangles split in two until no split
    pays.

    Each split is 2-means of the triangles' centroids, started across their principal axis, and each
    part gets the smallest sphere around its triangles' corners (which holds the triangles, a sphere
    being convex). Splitting stops at `max_spheres`, or when halving the largest sphere would shrink it
    by less than `WORTHWHILE_SHRINK` (the Panda's and the Z1's covers ship in ikdp/collision_spheres/).
    """
    centroids = triangles.mean(axis=1)
    clusters = [np.arange(len(triangles))]
    spheres = [enclosing_sphere(corners(triangles))]
    while len(spheres) < max_spheres:
        largest = max(range(len(spheres)), key=lambda index: spheres[index][1])
        second = split_in_two(centroids[clusters[largest]])
        if second is None:
            break
        halves = [clusters[largest][~second], clusters[largest][second]]
        covers = [enclosing_sphere(corners(triangles[half])) for half in halves]
        if max(radius for _, radius in covers) > WORTHWHILE_SHRINK * spheres[largest][1]:
            break
        clusters[largest : largest + 1], spheres[largest : largest + 1] = halves, covers
    return spheres


def corners(triangles: np.ndarray) -> np.ndarray:
    """(F, 3, 3) -> the distinct corners (P, 3)."""
    return np.unique(triangles.reshape(-1, 3), axis=0)


def split_in_two(points: np.ndarray, iterations: int = 20) -> np.ndarray | None:
    """2-means of the points (P, 3), started by the sign along their principal axis -> (P,) True for the second
    part; None if they cannot split."""
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
    return second


def enclosing_sphere(points: np.ndarray, iterations: int = 200) -> tuple[np.ndarray, float]:
    """A near-smallest sphere around the points (Badoiu and Clarkson 2003: step toward the farthest point)."""
    center = (points.max(axis=0) + points.min(axis=0)) / 2
    for iteration in range(iterations):
        farthest = points[np.argmax(((points - center) ** 2).sum(axis=1))]
        center = center + (farthest - center) / (iteration + 2)
    return center, float(np.sqrt(((points - center) ** 2).sum(axis=1).max()))  # every point inside, exactly
