"""A robot's link meshes for the 3-D viewer, read from the URDF the model was trained on (trimesh).

The collision meshes are preferred: the Panda's 9 collision meshes hold 1,168
vertices, and software WebGL pays for every one (its visual meshes are .dae, which
trimesh reads only with pycollada). Boxes, cylinders and spheres are built; a mesh
that cannot be read is left out (the skeletons still show the pose), never an
error: the viewer must open for any chain.

The K translucent ghosts get `light_mesh`es: software WebGL pays for every triangle
of every ghost in every frame (16 Panda ghosts are 37,000 triangles), and a faint
ghost reads as well with a 44-face hull. The hull is built here (`convex_hull`), not by
trimesh, whose hull needs scipy, which no user extra installs (without it a `[viz,robots]`
install drew nothing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from ikdp.rotations import origin_matrix


@dataclass(frozen=True)
class RobotMesh:
    """One mesh of one link, in that link's frame once `offset` is applied."""

    name: str  # unique scene-node name, e.g. "panda_link3_0"
    link_index: int  # index into arm.link_names of the link it hangs from
    offset: np.ndarray  # (4, 4) the geometry's origin in the link frame
    vertices: np.ndarray  # (V, 3) float32, scaled as the URDF asks
    faces: np.ndarray  # (F, 3) int32


def geometry_mesh(geometry) -> trimesh.Trimesh | None:
    """A URDF geometry as a trimesh in its own frame, or None if it cannot be built here."""
    if geometry.kind == "box":
        return trimesh.creation.box(extents=geometry.size)
    if geometry.kind == "cylinder":
        radius, length = geometry.size
        return trimesh.creation.cylinder(radius=radius, height=length, sections=16)
    if geometry.kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=1, radius=geometry.size[0])
    if geometry.kind != "mesh" or geometry.path is None:
        return None
    try:
        loaded = trimesh.load(geometry.path, force="mesh")
    except Exception:  # trimesh raises many kinds (a missing optional reader, a bad file): skip the mesh
        return None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        return None
    loaded.apply_scale(geometry.scale)
    return loaded


def robot_meshes(arm, *, prefer: str = "collision", chains=None) -> list[RobotMesh]:
    """Every drawable mesh of the arm's chain links; [] when the arm has no URDF at hand.

    `prefer`: "collision" (light) or "visual"; a link none of whose meshes of that kind can be read
    here (the Panda's visual .dae files need pycollada) falls back to the other kind. `chains`: the chains
    whose URDF links are drawn (a tree's, each link once: `arm.link_names`); None: the arm itself.
    """
    if prefer not in ("collision", "visual"):
        raise ValueError(f"prefer: expected 'collision' or 'visual', got {prefer!r}")
    descriptions = [chain.chain_description() for chain in ([arm] if chains is None else chains)]
    if any(description is None for description in descriptions):
        return []
    links = {link.name: link for description in descriptions for link in description.links}
    other = "visual" if prefer == "collision" else "collision"
    meshes = []
    for link_index, name in enumerate(arm.link_names):
        link = links.get(name)
        if link is None:
            continue
        for kind in (prefer, other):
            built = [(geometry, geometry_mesh(geometry)) for geometry in getattr(link, f"{kind}s")]
            built = [(geometry, mesh) for geometry, mesh in built if mesh is not None]
            if built:
                break
        for number, (geometry, mesh) in enumerate(built):
            meshes.append(
                RobotMesh(
                    name=f"{name}_{number}",
                    link_index=link_index,
                    offset=np.asarray(origin_matrix(geometry.origin), dtype=np.float64),
                    vertices=np.asarray(mesh.vertices, dtype=np.float32),
                    faces=np.asarray(mesh.faces, dtype=np.int32),
                )
            )
    return meshes


def light_mesh(vertices: np.ndarray, *, points: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """The convex hull of `points` vertices spread over the mesh (farthest-point order): (V, 3) float32, (F, 3) int32.

    At most 2 * points - 4 faces; a mesh with no more vertices than that is its own hull's corners.
    """
    vertices = np.asarray(vertices, dtype=np.float64)  # (V, 3)
    chosen = [0]
    distance = np.linalg.norm(vertices - vertices[0], axis=1)
    for _ in range(min(points, len(vertices)) - 1):
        index = int(distance.argmax())
        chosen.append(index)
        distance = np.minimum(distance, np.linalg.norm(vertices - vertices[index], axis=1))
    corners = vertices[chosen]  # (P, 3)
    faces = convex_hull(corners)
    used, faces = np.unique(faces, return_inverse=True)  # only the corners on the hull
    return corners[used].astype(np.float32), faces.reshape(-1, 3).astype(np.int32)


def convex_hull(points: np.ndarray) -> np.ndarray:
    """(F, 3) int indices into `points` (P, 3): the outward-wound triangles of their convex hull.

    Incremental: a first tetrahedron of far-apart points, then each point outside replaces the faces it
    sees by a fan to their horizon. O(P^2), meant for a few dozen points. Flat points give both sides
    of their 2-D hull; fewer than three points off one line give no faces.
    """
    points = np.asarray(points, dtype=np.float64)
    if len(points) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    tolerance = 1e-9 * max(float(np.ptp(points, axis=0).max()), 1e-300)
    a = 0
    b = int(np.linalg.norm(points - points[a], axis=1).argmax())
    off_line = np.linalg.norm(np.cross(points - points[a], points[b] - points[a]), axis=1)
    c = int(off_line.argmax())
    if off_line[c] <= tolerance * np.linalg.norm(points[b] - points[a]):
        return np.zeros((0, 3), dtype=np.int64)  # all on one line
    normal = np.cross(points[b] - points[a], points[c] - points[a])
    normal /= np.linalg.norm(normal)
    heights = (points - points[a]) @ normal
    d = int(np.abs(heights).argmax())
    if abs(heights[d]) <= tolerance:
        return flat_hull(points, normal)
    if heights[d] > 0:  # wind a, b, c so that d lies behind it
        b, c = c, b
    faces = np.array([(a, b, c), (a, d, b), (b, d, c), (c, d, a)])  # (F, 3)
    for point in range(len(points)):
        if point in (a, b, c, d):
            continue
        u, v, w = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]  # (F, 3) each
        normals = np.cross(v - u, w - u)
        areas = np.maximum(np.linalg.norm(normals, axis=1), 1e-300)
        heights = np.einsum("fk,fk->f", normals, points[point] - u) / areas  # in front of each face, signed
        seen = heights > tolerance
        if not seen.any():
            continue  # inside (or on) the hull so far
        seen_edges = {(int(face[i]), int(face[(i + 1) % 3])) for face in faces[seen] for i in range(3)}
        horizon = [(u, v, point) for u, v in seen_edges if (v, u) not in seen_edges]
        faces = np.concatenate([faces[~seen], np.array(horizon)])
    return faces.astype(np.int64)


def flat_hull(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Points on one plane: their 2-D hull (monotone chain) as a fan of triangles, wound both ways."""
    axis = np.eye(3)[int(np.abs(normal).argmin())]
    first = np.cross(normal, axis)
    first /= np.linalg.norm(first)
    second = np.cross(normal, first)
    flat = np.stack([points @ first, points @ second], axis=1)  # (P, 2)

    def chain(order) -> list[int]:
        kept: list[int] = []
        for index in order:
            while len(kept) >= 2:
                (x1, y1), (x2, y2) = flat[kept[-1]] - flat[kept[-2]], flat[index] - flat[kept[-2]]
                if x1 * y2 - y1 * x2 > 0:  # a left turn: keep
                    break
                kept.pop()
            kept.append(index)
        return kept[:-1]

    order = sorted(range(len(points)), key=lambda index: tuple(flat[index]))
    ring = chain(order) + chain(order[::-1])
    fan = [(ring[0], ring[i], ring[i + 1]) for i in range(1, len(ring) - 1)]
    return np.array(fan + [(u, w, v) for u, v, w in fan], dtype=np.int64).reshape(-1, 3)


# The planar scene's geometry, built with trimesh and sized to the arm: joint dots, the base, the target's cross.
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
