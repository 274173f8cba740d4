"""Shipped robots by name: which URDF and which end-effector link, and the paper's spatial arm.

The Panda, the UR5 and the Unitree Z1 come from the `example-robot-data` wheel (BSD-3; the Panda's files Apache-2.0),
found through its installed file list, so no site-packages path is written here. The paper's
spatial N-link arm (its equations 1-2) is built in code as a URDF string.
"""

from __future__ import annotations

from dataclasses import dataclass

from ikdp.chain_arm import ChainArm
from ikdp.robot_data import example_robot_data_file
from ikdp.urdf import parse_chain


@dataclass(frozen=True)
class RobotEntry:
    """Where a shipped robot's URDF is and which link is its end effector."""

    urdf: str  # path inside example-robot-data's `robots/` folder
    ee_link: str  # the end-effector link: targets are its pose in the base frame
    summary: str  # one line for listings


ROBOTS = {
    "panda": RobotEntry("panda_description/urdf/panda.urdf", "panda_hand", "Franka Emika Panda, 7 revolute joints"),
    "ur5": RobotEntry("ur_description/urdf/ur5_robot.urdf", "tool0", "Universal Robots UR5, 6 revolute joints"),
    # the gripper's fixed base (a link after joint6): the gripper's own joint stays off the chain
    "z1": RobotEntry("z1_description/urdf/z1.urdf", "gripperStator", "Unitree Z1, 6 revolute joints"),
}


def robot_names() -> list[str]:
    """Names `load_robot` accepts: the URDF robots, then `spatial<N>` for the paper's N-link arm."""
    return [*ROBOTS, "spatial<N>"]


def load_robot(name: str, target: str = "pose", ee_link: str | None = None) -> ChainArm:
    """A shipped robot by name -> ChainArm with `target` "pose" (B, 7) or "position" (B, 3) targets.

    `ee_link`: another end-effector link of the robot's URDF than its own (ValueError listing the links if
    it has none of that name); the spatial arm's is always its tip.
    """
    if name.startswith("spatial") and name[len("spatial") :].isdigit():
        if ee_link is not None:
            raise ValueError(f"ee_link: the spatial arm ends at its tip, got {ee_link!r}; --ee-link goes with a URDF")
        return spatial_arm(int(name[len("spatial") :]), target=target)
    if name not in ROBOTS:
        raise ValueError(f"name: unknown robot {name!r}, expected one of {robot_names()}")
    entry = ROBOTS[name]
    return ChainArm.from_urdf(example_robot_data_file(entry.urdf), ee_link or entry.ee_link, target=target)


def spatial_arm_urdf(num_links: int, *, bone_length: float = 1.0) -> str:
    """The paper's spatial N-link arm (eqs. 1-2) as a URDF: N bones of equal length along their link's x.

    The paper gives each bone absolute rotations about x, y and z; the tip sums the rotated bones.
    A rotation about the bone's own axis (x) does not move the bone, so each bone's direction is two
    angles. As a serial chain: at the start of bone n, a continuous joint about z (yaw) then one
    about y (pitch), relative to the bone before; 2N joints, the same reachable set (a ball of
    radius N * bone_length) and no joint limits. The end effector `tip` ends the last bone.
    """
    if not isinstance(num_links, int) or num_links < 1:
        raise ValueError(f"num_links: expected an integer >= 1, got {num_links!r}")
    if not bone_length > 0:
        raise ValueError(f"bone_length: expected a positive length, got {bone_length!r}")
    lines = [f'<robot name="spatial_arm_{num_links}">', '  <link name="base"/>']
    parent, offset = "base", 0.0
    for index in range(num_links):
        for axis_name, axis in (("yaw", "0 0 1"), ("pitch", "0 1 0")):
            child = f"bone{index}_{axis_name}"
            lines += [
                f'  <link name="{child}"/>',
                f'  <joint name="joint{index}_{axis_name}" type="continuous">',
                f'    <parent link="{parent}"/><child link="{child}"/>',
                f'    <origin xyz="{offset!r} 0 0"/><axis xyz="{axis}"/>',
                "  </joint>",
            ]
            parent, offset = child, 0.0
        offset = float(bone_length)
    lines += [
        '  <link name="tip"/>',
        '  <joint name="tip_joint" type="fixed">',
        f'    <parent link="{parent}"/><child link="tip"/><origin xyz="{offset!r} 0 0"/>',
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines)


def spatial_arm(num_links: int, *, bone_length: float = 1.0, target: str = "position") -> ChainArm:
    """The paper's spatial N-link arm as a ChainArm; position targets by default, as in the paper."""
    chain = parse_chain(spatial_arm_urdf(num_links, bone_length=bone_length), "tip")
    return ChainArm.from_description(chain, target=target)
