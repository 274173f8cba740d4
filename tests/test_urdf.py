"""The URDF chain reader: joints, limits, folded paths, meshes, and one-line refusals of bad input."""

from pathlib import Path

import pytest

from ikdp.robots import example_robot_data_file
from ikdp.urdf import link_names, parse_chain, read_chain

PANDA_URDF = "panda_description/urdf/panda.urdf"


def small_robot(joints: str, links: str = "") -> str:
    """A robot with links a, b, c, d and the given joints (plus any extra links)."""
    names = ["a", "b", "c", "d"]
    return "<robot name='small'>" + "".join(f"<link name='{name}'/>" for name in names) + links + joints + "</robot>"


def joint(name: str, kind: str, parent: str, child: str, extra: str = "<limit lower='-1' upper='1'/>") -> str:
    return f"<joint name='{name}' type='{kind}'><parent link='{parent}'/><child link='{child}'/>{extra}</joint>"


CHAIN = joint("ab", "revolute", "a", "b") + joint("bc", "continuous", "b", "c", "") + joint("cd", "fixed", "c", "d", "")


def one_line_error(function, *args, **kwargs) -> str:
    with pytest.raises(ValueError) as raised:
        function(*args, **kwargs)
    message = str(raised.value)
    assert "\n" not in message
    return message


def test_panda_chain_has_seven_limited_joints_and_the_hand_last():
    chain = read_chain(example_robot_data_file(PANDA_URDF), "panda_hand")
    assert chain.base_link == "panda_link0"
    assert [joint.name for joint in chain.movable_joints] == [f"panda_joint{index}" for index in range(1, 8)]
    assert [joint.type for joint in chain.joints[-2:]] == ["fixed", "fixed"]  # joint8 and the hand's
    fourth = chain.movable_joints[3]
    assert (fourth.lower, fourth.upper) == (-3.0718, -0.0698)
    assert fourth.origin.xyz == (0.0825, 0.0, 0.0)
    assert fourth.origin.rpy == pytest.approx((1.5707963267948966, 0.0, 0.0))
    assert [link.name for link in chain.links][-3:] == ["panda_link7", "panda_link8", "panda_hand"]


def test_panda_meshes_resolve_through_package_urls():
    chain = read_chain(example_robot_data_file(PANDA_URDF), "panda_hand")
    drawn = [link for link in chain.links if link.name != "panda_link8"]  # link8 is a bare frame
    for link in drawn:
        for geometry in (*link.visuals, *link.collisions):
            assert geometry.kind == "mesh" and geometry.filename.startswith("package://")
            assert geometry.path is not None and Path(geometry.path).is_file(), geometry.filename
        assert link.visuals[0].path.endswith(".dae") and link.collisions[0].path.endswith(".stl")


def test_package_url_searches_folders_beside_the_urdf(tmp_path):
    mesh = tmp_path / "my_pkg" / "meshes" / "part.stl"
    mesh.parent.mkdir(parents=True)
    mesh.write_text("solid part\nendsolid part\n")
    (tmp_path / "my_pkg" / "urdf").mkdir()
    geometry = (
        "<visual><origin xyz='0 0 0.5' rpy='0 0 1'/><geometry>"
        "<mesh filename='package://my_pkg/meshes/part.stl' scale='2 2 2'/></geometry></visual>"
        "<collision><geometry><mesh filename='../meshes/part.stl'/></geometry></collision>"
        "<collision><geometry><mesh filename='package://elsewhere/part.stl'/></geometry></collision>"
        "<collision><geometry><box size='1 2 3'/></geometry></collision>"
    )
    text = (
        f"<robot name='r'><link name='a'/><link name='b'>{geometry}</link>{joint('ab', 'prismatic', 'a', 'b')}</robot>"
    )
    urdf = tmp_path / "my_pkg" / "urdf" / "r.urdf"
    urdf.write_text(text)
    link = read_chain(urdf, "b").links[1]
    assert link.visuals[0].path == str(mesh.resolve())
    assert link.visuals[0].origin.xyz == (0.0, 0.0, 0.5) and link.visuals[0].scale == (2.0, 2.0, 2.0)
    assert link.collisions[0].path == str(mesh.resolve())  # relative to the URDF's folder
    assert link.collisions[1].path is None  # no such package anywhere: kept, unresolved
    assert link.collisions[2].kind == "box" and link.collisions[2].size == (1.0, 2.0, 3.0)


def test_limits_axis_and_fixed_joints_are_read():
    text = small_robot(
        joint("ab", "revolute", "a", "b", "<axis xyz='0 0 2'/><limit lower='-0.5' upper='0.25'/>")
        + joint("bc", "continuous", "b", "c", "<origin xyz='1 2 3' rpy='0.1 0.2 0.3'/>")
        + joint("cd", "fixed", "c", "d", "")
    )
    chain = parse_chain(text, "d")
    first, second, third = chain.joints
    assert first.axis == (0.0, 0.0, 1.0)  # normalised
    assert (first.lower, first.upper) == (-0.5, 0.25)
    assert second.axis == (1.0, 0.0, 0.0)  # URDF's default axis
    assert (second.lower, second.upper) == (None, None)  # continuous: no limits
    assert second.origin.xyz == (1.0, 2.0, 3.0) and second.origin.rpy == (0.1, 0.2, 0.3)
    assert third.type == "fixed" and [joint.name for joint in chain.movable_joints] == ["ab", "bc"]


def test_default_base_is_the_top_of_the_end_effectors_tree():
    two_trees = small_robot(joint("ab", "revolute", "a", "b") + joint("cd", "prismatic", "c", "d"))
    assert parse_chain(two_trees, "d").base_link == "c"
    assert parse_chain(two_trees, "b").base_link == "a"


def test_joints_off_the_path_stay_off_the_chain_whatever_their_type_and_their_links_hang_from_it():
    text = small_robot(joint("ab", "revolute", "a", "b") + joint("ac", "floating", "a", "c", ""))
    chain = parse_chain(text, "b")
    assert [joint.name for joint in chain.joints] == ["ab"]
    assert [(item.link.name, item.parent, [joint.type for joint in item.joints]) for item in chain.hanging] == [
        ("c", 0, ["fixed"])  # a floating joint off the chain is held at its origin
    ]
    below = small_robot(
        joint("ab", "revolute", "a", "b") + joint("bc", "fixed", "b", "c", "") + joint("cd", "prismatic", "c", "d")
    )
    assert [
        (item.link.name, item.parent, [j.name for j in item.joints]) for item in parse_chain(below, "b").hanging
    ] == [
        ("c", 1, ["bc"]),
        ("d", 1, ["bc", "cd"]),  # past the end effector, two joints down
    ]


def test_the_panda_fingers_hang_from_its_hand_one_mimicking_the_other():
    chain = read_chain(example_robot_data_file(PANDA_URDF), "panda_hand")
    hanging = {item.link.name: item for item in chain.hanging}
    assert sorted(hanging) == ["panda_hand_tcp", "panda_leftfinger", "panda_rightfinger"]
    assert {chain.links[item.parent].name for item in hanging.values()} == {"panda_hand"}
    (left,), (right,) = hanging["panda_leftfinger"].joints, hanging["panda_rightfinger"].joints
    assert (left.type, left.lower, left.upper, left.axis, left.mimic) == ("prismatic", 0.0, 0.04, (0.0, 1.0, 0.0), None)
    assert right.mimic == ("panda_finger_joint1", 1.0, 0.0) and right.axis == (0.0, -1.0, 0.0)
    assert len(hanging["panda_leftfinger"].link.collisions) == 4  # boxes: mount, sledge, diagonal, tip


def test_missing_file_is_refused(tmp_path):
    assert "no file" in one_line_error(read_chain, tmp_path / "absent.urdf", "hand")


def test_missing_link_is_refused():
    assert "'hand'" in one_line_error(parse_chain, small_robot(CHAIN), "hand")
    assert "'nowhere'" in one_line_error(parse_chain, small_robot(CHAIN), "d", base_link="nowhere")


def test_branch_that_is_not_a_chain_is_refused():
    branches = small_robot(joint("ab", "revolute", "a", "b") + joint("ac", "revolute", "a", "c"))
    assert "not an ancestor" in one_line_error(parse_chain, branches, "c", base_link="b")
    two_parents = small_robot(joint("ab", "revolute", "a", "b") + joint("cb", "revolute", "c", "b"))
    assert "not a tree" in one_line_error(parse_chain, two_parents, "b")
    loop = small_robot(joint("ab", "revolute", "a", "b") + joint("ba", "revolute", "b", "a"))
    assert "loop" in one_line_error(parse_chain, loop, "b")
    only_fixed = small_robot(joint("ab", "fixed", "a", "b", ""))
    assert "no movable joint" in one_line_error(parse_chain, only_fixed, "b")


def test_unsupported_joint_type_and_missing_limits_are_refused():
    floating = small_robot(joint("ab", "floating", "a", "b", ""))
    assert "'floating'" in one_line_error(parse_chain, floating, "b")
    no_limits = small_robot(joint("ab", "revolute", "a", "b", "<axis xyz='0 0 1'/>"))
    assert "needs <limit" in one_line_error(parse_chain, no_limits, "b")
    assert "not well-formed" in one_line_error(parse_chain, "<robot><link name='a'></robot>", "a")
    bad_origin = small_robot(joint("ab", "revolute", "a", "b", "<origin xyz='1 2'/><limit lower='0' upper='1'/>"))
    assert "3 numbers" in one_line_error(parse_chain, bad_origin, "b")


# --- what a user's URDF brings: example-robot-data's arms beyond the Panda ------------------------
Z1_URDF = "z1_description/urdf/z1.urdf"
KINOVA_URDF = "kinova_description/robots/kinova.urdf"


def test_z1_reads_through_dynamics_transmissions_and_a_fixed_tool_link():
    chain = read_chain(example_robot_data_file(Z1_URDF), "gripperStator")
    assert chain.base_link == "world"  # the root, above a fixed joint to the arm's own base
    assert [joint.name for joint in chain.movable_joints] == [f"joint{index}" for index in range(1, 7)]
    assert [joint.type for joint in (chain.joints[0], chain.joints[-1])] == ["fixed", "fixed"]
    second = chain.movable_joints[1]
    assert (second.lower, second.upper) == (0.0, 2.9670597283903604)  # beside <dynamics damping friction>
    assert all(geometry.path is not None for link in chain.links[1:] for geometry in link.visuals)


def test_continuous_joints_ignore_a_limit_the_urdf_gives_them():
    chain = read_chain(example_robot_data_file(KINOVA_URDF), "j2s6s200_end_effector")
    kinds = [joint.type for joint in chain.movable_joints]
    assert kinds == ["continuous", "revolute", "revolute", "continuous", "revolute", "continuous"]
    first = chain.movable_joints[0]
    assert (first.lower, first.upper) == (None, None)  # its <limit lower="-6.28" upper="6.28"> is not a limit


def test_unknown_end_effector_names_the_links_to_choose_from():
    message = one_line_error(read_chain, example_robot_data_file(Z1_URDF), "Fixed_Jaw")
    assert message.startswith("ee_link: no link 'Fixed_Jaw'") and "link06, gripperStator, gripperMover" in message
    assert link_names(small_robot(CHAIN)) == ["a", "b", "c", "d"]
    many = "<robot name='r'>" + "".join(f"<link name='l{index}'/>" for index in range(25)) + "</robot>"
    assert one_line_error(parse_chain, many, "hand").endswith("l19 and 5 more")


def test_a_mimic_joint_on_the_chain_is_refused_and_one_off_it_is_not():
    mimic = "<limit lower='-1' upper='1'/><mimic joint='ab' multiplier='-1'/>"
    fingers = small_robot(joint("ab", "revolute", "a", "b") + joint("bc", "revolute", "b", "c", mimic))
    assert "mimics 'ab'" in one_line_error(parse_chain, fingers, "c")
    assert [joint.name for joint in parse_chain(fingers, "b").joints] == ["ab"]


def test_xacro_and_unexpanded_numbers_are_refused_in_one_line():
    xacro = (
        "<robot name='r' xmlns:xacro='http://www.ros.org/wiki/xacro'><xacro:property name='pi' value='3.14'/>"
        "<link name='a'/></robot>"
    )
    assert "xacro" in one_line_error(parse_chain, xacro, "a")
    unexpanded = small_robot(joint("ab", "revolute", "a", "b", "<limit lower='-${pi}' upper='1'/>"))
    message = one_line_error(parse_chain, unexpanded, "b")
    assert "joint 'ab' lower limit" in message and "'-${pi}'" in message


def test_a_floating_joint_on_the_chain_says_to_start_below_it():
    mobile = small_robot(joint("ab", "floating", "a", "b", "") + joint("bc", "revolute", "b", "c"))
    assert "base_link" in one_line_error(parse_chain, mobile, "c")
    assert [joint.name for joint in parse_chain(mobile, "c", base_link="b").joints] == ["bc"]
