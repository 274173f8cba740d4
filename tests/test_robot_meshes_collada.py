"""A URDF whose meshes are COLLADA files only (the Kinova Jaco 2's .dae) is drawn with its meshes, not skeletons:
trimesh reads .dae through pycollada, which the [viz] extra installs."""

import pytest

from ikdp.chain_arm import ChainArm
from ikdp.robots import example_robot_data_file

pytest.importorskip("trimesh")
from ikdp_viz.robot_meshes import robot_meshes  # noqa: E402


def test_a_urdf_with_only_collada_meshes_gets_every_chain_link_drawn():
    path = example_robot_data_file("kinova_description/robots/kinova.urdf")
    assert 'filename="package://example-robot-data/robots/kinova_description/meshes/base.dae"' in open(path).read()
    arm = ChainArm.from_urdf(path, "j2s6s200_end_effector")
    meshes = robot_meshes(arm)
    drawn_links = {mesh.link_index for mesh in meshes}
    assert len(drawn_links) >= arm.num_joints  # every moving link has a mesh (the base too)
    assert all(len(mesh.faces) > 0 and mesh.vertices.shape[1] == 3 for mesh in meshes)
