"""A robot's link meshes for the 3-D viewer, read from the URDF the model was trained on (trimesh).

The collision meshes are preferred: the Panda's 9 collision meshes hold 1,168
vertices, and software WebGL pays for every one (its visual meshes are .dae, which
trimesh reads only with pycollada). Boxes, cylinders and spheres are built; a mesh
that cannot be read is left out (the skeletons still show the pose), never an
error: the viewer must open for any chain.

The K translucent ghosts get `light_mesh`es: software WebGL pays for every triangle
of every ghost in every frame (16 Panda ghosts are 37,000 triangles), and a faint
ghost reads as well with a 44-face hull.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from ikdp.chain_arm import origin_matrix


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


def robot_meshes(arm, *, prefer: str = "collision") -> list[RobotMesh]:
    """Every drawable mesh of the arm's chain links; [] when the arm has no URDF at hand.

    `prefer`: "collision" (light) or "visual"; a link none of whose meshes of that kind can be read
    here (the Panda's visual .dae files need pycollada) falls back to the other kind.
    """
    if prefer not in ("collision", "visual"):
        raise ValueError(f"prefer: expected 'collision' or 'visual', got {prefer!r}")
    description = arm.chain_description()
    if description is None:
        return []
    links = {link.name: link for link in description.links}
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

    At most 2 * points - 4 faces; a mesh with no more vertices than that, or a flat one, is its own hull.
    """
    vertices = np.asarray(vertices, dtype=np.float64)  # (V, 3)
    chosen = [0]
    distance = np.linalg.norm(vertices - vertices[0], axis=1)
    for _ in range(min(points, len(vertices)) - 1):
        index = int(distance.argmax())
        chosen.append(index)
        distance = np.minimum(distance, np.linalg.norm(vertices - vertices[index], axis=1))
    try:
        hull = trimesh.convex.convex_hull(vertices[chosen])
    except Exception:  # qhull refuses flat or degenerate point sets: the whole mesh's hull then
        hull = trimesh.convex.convex_hull(vertices)
    return np.asarray(hull.vertices, dtype=np.float32), np.asarray(hull.faces, dtype=np.int32)
