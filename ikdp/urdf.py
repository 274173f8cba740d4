"""Read a serial chain (base link -> end-effector link) from a URDF, with the standard library's XML parser.

The result is a plain description, no maths: every joint on the path from the base link to the
end-effector link in order (fixed ones included, so the viewer can place every link), every link
on that path with its visual and collision geometry, and the file it came from. `ChainArm`
(ikdp/chain_arm.py) folds the fixed joints into the offsets of the moving ones.

Supported joints: revolute (limits required, as URDF requires), continuous (no limits, the angle
wraps; a <limit> on one is ignored), prismatic (limits required) and fixed. Anything else on the
path (floating, planar) is refused, and so is a joint on the path that mimics another (the model
treats every joint as free). Links off the path that hang from a link on it (a gripper's fingers,
a camera on a fixed joint, whatever follows the end effector) move with the chain: they are kept
as `hanging` links, each with the joints from its chain link down to it, of any type and mimic
included (the collision model holds their joints at stated values, ikdp/link_spheres.py).
<dynamics>, <transmission>, <gazebo> and other elements are ignored. A xacro file is refused with
the command that expands it.

Mesh filenames `package://PKG/rest` are resolved by searching, from the URDF's folder upwards,
for a folder `PKG/rest` or a folder named PKG holding `rest` (how ROS and example-robot-data
lay packages out), then any `package_dirs` given.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path

SUPPORTED_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed")
MOVABLE_JOINT_TYPES = ("revolute", "continuous", "prismatic")
XACRO_TAG = "{http://www.ros.org/wiki/xacro}"  # ElementTree's spelling of the xacro: namespace


@dataclass(frozen=True)
class Origin:
    """A rigid offset as URDF writes it: translation in metres, then fixed-axis roll-pitch-yaw in radians."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)  # translation, metres, in the parent frame
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)  # roll about x, pitch about y, yaw about z; radians


@dataclass(frozen=True)
class Geometry:
    """One visual or collision element of a link, in the link's frame."""

    kind: str  # "mesh", "box", "cylinder" or "sphere"
    origin: Origin  # where the element sits in its link's frame
    filename: str | None = None  # a mesh's filename as the URDF writes it (package://, file:// or relative)
    path: str | None = None  # that mesh resolved to an existing file, or None if it could not be found
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)  # a mesh's scale per axis
    size: tuple[float, ...] = ()  # box (x, y, z); cylinder (radius, length); sphere (radius,)


@dataclass(frozen=True)
class LinkDescription:
    """A link on the chain and what to draw for it."""

    name: str  # the link's name in the URDF
    visuals: tuple[Geometry, ...]  # detailed meshes, for looking at
    collisions: tuple[Geometry, ...]  # light meshes, for many ghost robots at once


@dataclass(frozen=True)
class JointDescription:
    """A joint on the chain, as the URDF gives it."""

    name: str  # the joint's name in the URDF
    type: str  # one of SUPPORTED_JOINT_TYPES
    parent: str  # parent link's name
    child: str  # child link's name
    origin: Origin  # the child's joint frame in the parent link's frame, at joint value zero
    axis: tuple[float, float, float]  # unit axis in the joint frame (URDF's default is x)
    lower: float | None  # lower limit, radians or metres; None for continuous and fixed joints
    upper: float | None  # upper limit; None for continuous and fixed joints
    mimic: tuple[str, float, float] | None = None  # off the chain only: (joint it follows, multiplier, offset)


@dataclass(frozen=True)
class HangingLink:
    """A link off the chain that hangs from a link on it, so it moves with the chain (a gripper's finger)."""

    link: LinkDescription  # its name and geometry
    parent: int  # the chain link it hangs from, an index into ChainDescription.links
    joints: tuple[JointDescription, ...]  # from that chain link down to it; off-chain joints of any type


@dataclass(frozen=True)
class ChainDescription:
    """The serial chain from `base_link` to `ee_link`: joints in order from the base, links base first."""

    robot_name: str  # the <robot name="...">
    base_link: str  # where the chain starts: the frame targets are written in
    ee_link: str  # the end-effector link
    joints: tuple[JointDescription, ...]  # every joint on the path, fixed ones included, base first
    links: tuple[LinkDescription, ...]  # base_link, then each joint's child in order
    urdf_path: str | None  # the file it was read from (None when parsed from a string)
    hanging: tuple[HangingLink, ...] = ()  # links off the chain that hang from it, depth first

    @property
    def movable_joints(self) -> tuple[JointDescription, ...]:
        return tuple(joint for joint in self.joints if joint.type in MOVABLE_JOINT_TYPES)


def read_chain(
    urdf_path: str | Path, ee_link: str, *, base_link: str | None = None, package_dirs=()
) -> ChainDescription:
    """Read the chain from `base_link` (default: the root of `ee_link`'s tree) to `ee_link` from a URDF file."""
    path = Path(urdf_path)
    if not path.is_file():
        raise ValueError(f"urdf_path: no file at {str(path)!r}")
    text = path.read_text(encoding="utf-8")
    return parse_chain(text, ee_link, base_link=base_link, urdf_path=path.resolve(), package_dirs=package_dirs)


def parse_chain(
    urdf_text: str,
    ee_link: str,
    *,
    base_link: str | None = None,
    urdf_path: str | Path | None = None,
    package_dirs=(),
) -> ChainDescription:
    """Parse URDF text and extract the chain to `ee_link`; `urdf_path` (if any) anchors mesh lookups."""
    try:
        root = ElementTree.fromstring(urdf_text)
    except ElementTree.ParseError as error:
        raise ValueError(f"urdf: not well-formed XML ({error})") from None
    if root.tag != "robot":
        raise ValueError(f"urdf: expected a <robot> root element, got <{root.tag}>")
    if any(element.tag.startswith(XACRO_TAG) for element in root.iter()):
        raise ValueError(
            "urdf: this is a xacro file (it has <xacro:...> elements): expand it first, `xacro in.xacro > out.urdf`"
        )

    link_elements = {}
    for element in root.findall("link"):
        name = _required_attribute(element, "name", "link")
        link_elements[name] = element
    joint_to_child = {}  # child link -> its joint element
    for element in root.findall("joint"):
        joint_name = _required_attribute(element, "name", "joint")
        child = _required_attribute(
            _required_child(element, "child", joint_name), "link", f"joint {joint_name!r} child"
        )
        if child in joint_to_child:
            other = joint_to_child[child].get("name")
            raise ValueError(f"urdf: link {child!r} is the child of joints {other!r} and {joint_name!r}: not a tree")
        joint_to_child[child] = element

    if ee_link not in link_elements:
        raise ValueError(f"ee_link: no link {ee_link!r} in the URDF; {links_phrase(list(link_elements))}")
    if base_link is not None and base_link not in link_elements:
        raise ValueError(f"base_link: no link {base_link!r} in the URDF")

    path_joints = []  # walked from the end effector up, reversed below
    link = ee_link
    while link != base_link:
        element = joint_to_child.get(link)
        if element is None:
            if base_link is None:  # the top of the end effector's tree is the base
                base_link = link
                break
            raise ValueError(f"base_link: {base_link!r} is not an ancestor of ee_link {ee_link!r}: no chain joins them")
        path_joints.append(element)
        link = _required_attribute(_required_child(element, "parent", element.get("name")), "link", "joint parent")
        if len(path_joints) > len(joint_to_child):
            raise ValueError(f"urdf: the joints above {ee_link!r} form a loop, not a chain")
    path_joints.reverse()

    urdf_dir = Path(urdf_path).resolve().parent if urdf_path is not None else None
    search_dirs = _package_search_dirs(urdf_dir, package_dirs)
    joints = tuple(_read_joint(element) for element in path_joints)
    if not any(joint.type in MOVABLE_JOINT_TYPES for joint in joints):
        raise ValueError(f"ee_link: no movable joint between {base_link!r} and {ee_link!r}")
    link_names = [base_link] + [joint.child for joint in joints]
    links = tuple(_read_link(link_elements[name], urdf_dir, search_dirs) for name in link_names)
    children = {}  # parent link -> its joints' elements, in file order
    for element in joint_to_child.values():
        children.setdefault(element.find("parent").get("link"), []).append(element)
    hanging = []
    on_chain = set(link_names)
    for parent, name in enumerate(link_names):
        pending = [
            (element, ()) for element in children.get(name, []) if element.find("child").get("link") not in on_chain
        ]
        while pending:  # depth first below the chain link
            element, above = pending.pop(0)
            joint = _read_hanging_joint(element)
            hanging.append(
                HangingLink(_read_link(link_elements[joint.child], urdf_dir, search_dirs), parent, (*above, joint))
            )
            pending[:0] = [(below, (*above, joint)) for below in children.get(joint.child, [])]
    return ChainDescription(
        robot_name=root.get("name", ""),
        base_link=base_link,
        ee_link=ee_link,
        joints=joints,
        links=links,
        urdf_path=str(urdf_path) if urdf_path is not None else None,
        hanging=tuple(hanging),
    )


def resolve_mesh_filename(filename: str, urdf_dir: Path | None, search_dirs: tuple[Path, ...]) -> str | None:
    """A mesh filename from a URDF -> an existing absolute path, or None if nothing matches."""
    if filename.startswith("package://"):
        package, _, rest = filename[len("package://") :].partition("/")
        for folder in search_dirs:
            for candidate in (folder / package / rest, folder / rest if folder.name == package else None):
                if candidate is not None and candidate.is_file():
                    return str(candidate)
        return None
    if filename.startswith("file://"):
        candidate = Path(filename[len("file://") :])
    else:
        candidate = Path(filename)
        if not candidate.is_absolute() and urdf_dir is not None:
            candidate = urdf_dir / candidate
    return str(candidate.resolve()) if candidate.is_file() else None


def link_names(urdf_text: str) -> list[str]:
    """Every link's name, in file order: the choices of an end-effector (and base) link."""
    try:
        root = ElementTree.fromstring(urdf_text)
    except ElementTree.ParseError as error:
        raise ValueError(f"urdf: not well-formed XML ({error})") from None
    return [element.get("name") for element in root.findall("link")]


def links_phrase(names: list[str], shown: int = 20) -> str:
    """ "its links: a, b, c" for an error message, shortened past `shown` names."""
    if not names:
        return "it has no links"
    listed = ", ".join(names[:shown]) + (f" and {len(names) - shown} more" if len(names) > shown else "")
    return f"its links: {listed}"


# --- element readers ---------------------------------------------------------------------------
def _required_attribute(element, attribute: str, what: str) -> str:
    value = element.get(attribute)
    if value is None:
        raise ValueError(f"urdf: {what} has no {attribute!r} attribute")
    return value


def _required_child(element, tag: str, what) -> ElementTree.Element:
    child = element.find(tag)
    if child is None:
        raise ValueError(f"urdf: joint {what!r} has no <{tag}>")
    return child


def _floats(text: str | None, count: int, default: tuple[float, ...], what: str) -> tuple[float, ...]:
    if text is None:
        return default
    try:
        values = tuple(float(value) for value in text.split())
    except ValueError:
        raise ValueError(f"urdf: {what} expected {count} numbers, got {text!r}") from None
    if len(values) != count:
        raise ValueError(f"urdf: {what} expected {count} numbers, got {text!r}")
    return values


def _float(text: str | None, what: str, default: float | None = None) -> float:
    """One number from an attribute; a one-line error naming it when it is missing or not a number."""
    if text is None and default is not None:
        return default
    try:
        return float(text)
    except (TypeError, ValueError):
        raise ValueError(f"urdf: {what} expected a number, got {text!r}") from None


def _read_origin(element, what: str) -> Origin:
    if element is None:
        return Origin()
    return Origin(
        xyz=_floats(element.get("xyz"), 3, (0.0, 0.0, 0.0), f"{what} origin xyz"),
        rpy=_floats(element.get("rpy"), 3, (0.0, 0.0, 0.0), f"{what} origin rpy"),
    )


def _read_joint(element) -> JointDescription:
    name = element.get("name")
    joint_type = element.get("type")
    if joint_type not in SUPPORTED_JOINT_TYPES:
        raise ValueError(
            f"urdf: joint {name!r} on the chain has type {joint_type!r}, expected one of {SUPPORTED_JOINT_TYPES} "
            f"(to start the chain below it, give base_link)"
        )
    axis_element = element.find("axis")
    axis = _floats(
        axis_element.get("xyz") if axis_element is not None else None, 3, (1.0, 0.0, 0.0), f"joint {name!r} axis"
    )
    norm = math.sqrt(sum(value * value for value in axis))
    if joint_type != "fixed" and not norm > 0:
        raise ValueError(f"urdf: joint {name!r} has a zero axis")
    axis = tuple(value / norm for value in axis) if norm > 0 else axis
    mimic = element.find("mimic")
    if mimic is not None and joint_type != "fixed":
        raise ValueError(
            f"urdf: joint {name!r} on the chain mimics {mimic.get('joint')!r}; IKDP moves every joint freely: "
            f"choose an ee_link above it"
        )
    lower = upper = None
    if joint_type in ("revolute", "prismatic"):
        limit = element.find("limit")
        if limit is None or limit.get("lower") is None or limit.get("upper") is None:
            raise ValueError(f"urdf: {joint_type} joint {name!r} needs <limit lower=... upper=...>")
        lower = _float(limit.get("lower"), f"joint {name!r} lower limit")
        upper = _float(limit.get("upper"), f"joint {name!r} upper limit")
        if not lower <= upper:
            raise ValueError(f"urdf: joint {name!r} has lower limit {lower} above upper limit {upper}")
    return JointDescription(
        name=name,
        type=joint_type,
        parent=element.find("parent").get("link"),
        child=element.find("child").get("link"),
        origin=_read_origin(element.find("origin"), f"joint {name!r}"),
        axis=axis,
        lower=lower,
        upper=upper,
    )


def _read_hanging_joint(element) -> JointDescription:
    """A joint off the chain, read leniently: it is never moved by IK, only held at a value.

    A floating or planar joint is held at its origin (read as fixed); a missing limit is None; a mimic
    joint records what it follows.
    """
    name = element.get("name")
    joint_type = element.get("type") if element.get("type") in SUPPORTED_JOINT_TYPES else "fixed"
    axis_element = element.find("axis")
    axis = _floats(
        axis_element.get("xyz") if axis_element is not None else None, 3, (1.0, 0.0, 0.0), f"joint {name!r} axis"
    )
    norm = math.sqrt(sum(value * value for value in axis))
    if not norm > 0:
        joint_type, axis = "fixed", (1.0, 0.0, 0.0)
    limit = element.find("limit") if joint_type in ("revolute", "prismatic") else None
    lower = upper = None
    if limit is not None and limit.get("lower") is not None and limit.get("upper") is not None:
        lower = _float(limit.get("lower"), f"joint {name!r} lower limit")
        upper = _float(limit.get("upper"), f"joint {name!r} upper limit")
    mimic = element.find("mimic")
    return JointDescription(
        name=name,
        type=joint_type,
        parent=_required_attribute(_required_child(element, "parent", name), "link", f"joint {name!r} parent"),
        child=_required_attribute(_required_child(element, "child", name), "link", f"joint {name!r} child"),
        origin=_read_origin(element.find("origin"), f"joint {name!r}"),
        axis=tuple(value / norm for value in axis) if norm > 0 else axis,
        lower=lower,
        upper=upper,
        mimic=None
        if mimic is None or joint_type == "fixed"
        else (
            _required_attribute(mimic, "joint", f"joint {name!r} mimic"),
            _float(mimic.get("multiplier"), f"joint {name!r} mimic multiplier", 1.0),
            _float(mimic.get("offset"), f"joint {name!r} mimic offset", 0.0),
        ),
    )


def _read_geometry(element, what: str, urdf_dir: Path | None, search_dirs: tuple[Path, ...]) -> Geometry | None:
    geometry = element.find("geometry")
    if geometry is None or len(geometry) == 0:
        return None
    shape = geometry[0]
    origin = _read_origin(element.find("origin"), what)
    if shape.tag == "mesh":
        filename = _required_attribute(shape, "filename", f"{what} mesh")
        return Geometry(
            kind="mesh",
            origin=origin,
            filename=filename,
            path=resolve_mesh_filename(filename, urdf_dir, search_dirs),
            scale=_floats(shape.get("scale"), 3, (1.0, 1.0, 1.0), f"{what} mesh scale"),
        )
    if shape.tag == "box":
        return Geometry(kind="box", origin=origin, size=_floats(shape.get("size"), 3, (0.0, 0.0, 0.0), f"{what} box"))
    if shape.tag == "cylinder":
        radius = _float(shape.get("radius"), f"{what} cylinder radius", 0.0)
        length = _float(shape.get("length"), f"{what} cylinder length", 0.0)
        return Geometry(kind="cylinder", origin=origin, size=(radius, length))
    if shape.tag == "sphere":
        return Geometry(kind="sphere", origin=origin, size=(_float(shape.get("radius"), f"{what} sphere radius", 0.0),))
    return None  # a geometry we cannot draw (capsule, heightfield): nothing to keep


def _read_link(element, urdf_dir: Path | None, search_dirs: tuple[Path, ...]) -> LinkDescription:
    name = element.get("name")
    geometries = {}
    for tag in ("visual", "collision"):
        read = (_read_geometry(item, f"link {name!r} {tag}", urdf_dir, search_dirs) for item in element.findall(tag))
        geometries[tag] = tuple(geometry for geometry in read if geometry is not None)
    return LinkDescription(name=name, visuals=geometries["visual"], collisions=geometries["collision"])


def _package_search_dirs(urdf_dir: Path | None, package_dirs) -> tuple[Path, ...]:
    """The URDF's folder and each folder above it, then the folders the caller named."""
    folders = [] if urdf_dir is None else [urdf_dir, *urdf_dir.parents]
    return tuple(folders) + tuple(Path(folder) for folder in package_dirs)
