"""The Z1 drawn with gaps between its links: each mesh sits where the URDF puts it; the gaps are the URDF's own
collision geometry (a few cylinders per link, none on two links), not a misplaced mesh."""

from __future__ import annotations

import numpy as np
from viz_helpers import shipped_solver_or_skip

from ikdp.rotations import origin_matrix
from ikdp_viz.robot_meshes import robot_meshes


def z1_arm_and_links():
    arm = shipped_solver_or_skip("ikdp_z1").arm
    description = arm.chain_description()
    return arm, {link.name: link for link in description.links}


def test_each_z1_mesh_is_placed_at_its_urdf_origin_collision_first_visual_where_a_link_has_none():
    arm, links = z1_arm_and_links()
    meshes = robot_meshes(arm)
    assert meshes, "the Z1's URDF meshes could not be read here"
    for mesh in meshes:
        name, number = mesh.name.rsplit("_", 1)
        link = links[name]
        geometries = link.collisions or link.visuals  # the viewer's choice: collision, else visual
        assert arm.link_names[mesh.link_index] == name
        assert np.allclose(mesh.offset, origin_matrix(geometries[int(number)].origin))  # the URDF's origin, as is
    drawn = {mesh.name.rsplit("_", 1)[0] for mesh in meshes}
    assert {"link01", "link05"} <= drawn  # no collision geometry there: their visual meshes are drawn instead
    assert not links["link01"].collisions and not links["link05"].collisions


def test_the_z1_s_collision_cylinders_leave_gaps_along_its_upper_arm():
    """link02's three collision cylinders (two joint housings about y, a tube along x between them) do not touch:
    the drawn gaps are in the URDF."""
    arm, _ = z1_arm_and_links()
    pieces = [mesh for mesh in robot_meshes(arm) if mesh.name.startswith("link02_")]
    assert len(pieces) == 3
    spans = []
    for mesh in pieces:
        placed = mesh.vertices.astype(np.float64) @ mesh.offset[:3, :3].T + mesh.offset[:3, 3]
        spans.append((placed[:, 0].min(), placed[:, 0].max()))
    spans.sort()
    gaps = [later[0] - earlier[1] for earlier, later in zip(spans[:-1], spans[1:], strict=True)]
    assert all(gap > 0.01 for gap in gaps), spans  # more than 10 mm of nothing between each pair
