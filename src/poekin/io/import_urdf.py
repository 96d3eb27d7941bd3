"""Reading a :class:`~poekin.tree.Tree` from a URDF file.

The file is parsed with `yourdfpy <https://github.com/clemense/yourdfpy>`_ (the extra
``poekin[urdf]``) without loading any mesh, so ``package://`` URIs and missing mesh files never
matter: kinematics needs links and joints only.

Every link is a body named after it, posed in its parent link by its parent joint's
``<origin xyz rpy>`` (``R = Rz(yaw) Ry(pitch) Rx(roll)``). URDF joints turn about the child
link's origin, so anchors and ``ref`` are 0:

========================  ===========================================================
URDF joint                tree joint
========================  ===========================================================
revolute                  ``"revolute"``, limits from ``<limit lower upper>`` (below)
continuous                ``"revolute"``, no limits
prismatic                 ``"prismatic"``, limits from ``<limit lower upper>`` (below)
fixed                     none: the child link stays a body (a frame)
floating                  ``"free"``, on a child of a root link named ``world`` only
spherical                 ``"ball"`` (Bullet's extension of URDF, which MuJoCo reads too)
planar                    refused (:class:`~poekin.errors.URDFError`)
========================  ===========================================================

``<axis>`` defaults to ``1 0 0`` and is divided by its norm, as MuJoCo does (which refuses a
squared norm under ``1e-14``). ``<mimic>`` makes a :class:`~poekin.tree.Mimic` joint with no
``qpos`` entry; its leader may come before or after it.

Limits are MuJoCo's: a revolute or prismatic joint is limited to ``[lower, upper]`` when both
are given and ``lower < upper``, and is unlimited otherwise: ``lower > upper`` (Bullet's way to
say "no limit"), ``lower = upper``, a ``<limit>`` without ``lower`` or ``upper`` (which the
URDF spec reads as 0, a locked joint) or no ``<limit>``. A :class:`URDFLimitsWarning` names
those joints.

This is how MuJoCo compiles the same URDF with ``compiler.fusestatic = False``: the same bodies
in the same order (a root link named ``world`` is MuJoCo's world body, not a body), the same
joint names; MuJoCo's ``qpos`` holds mimic followers too, tied by equality constraints.

What poekin reads is checked first, and a file is refused (:class:`~poekin.errors.URDFError`,
one line naming the joint, the element and the fix) rather than guessed at: an ``<origin>`` or
``<axis>`` without exactly 3 finite numbers, a joint with two ``<parent>``, ``<child>``,
``<origin>``, ``<axis>``, ``<limit>`` or ``<mimic>`` elements, a xacro file not yet expanded.
Of a link, poekin reads its ``<inertial>``'s ``<mass value>`` and ``<origin xyz>`` only (the
body's :attr:`~poekin.tree.Tree.body_mass` and :attr:`~poekin.tree.Tree.body_com`, for
:meth:`~poekin.tree.Tree.com`; a link without ``<inertial>`` is massless, as in MuJoCo and
Pinocchio), and checks those: one ``<inertial>``, one finite ``<mass value>`` ``>= 0`` (MuJoCo
and urdfdom refuse an ``<inertial>`` without one), and its ``<origin>``'s numbers. The inertia
tensor and geometry are not read, so not checked. Every link stays a body, a fixed joint's
child too, so its mass stays where it is; a root link named ``world`` is the world, whose
mass MuJoCo and Pinocchio leave out of the centre of mass too. Blank lines before
``<?xml ...?>`` are accepted, as MuJoCo and Pinocchio accept them.
"""

from __future__ import annotations

import io
import math
import os
import pathlib
import re
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from poekin.errors import InputError, URDFError, did_you_mean
from poekin.tree import Mimic, Tree, TreeJointType

if TYPE_CHECKING:
    import xml.etree.ElementTree as ET

__all__ = ["FLOATING_BASE", "URDFLimitsWarning", "parse_urdf", "tree_from_urdf"]

FLOATING_BASE = "floating_base"
"""Name of the free joint that ``floating_base=True`` puts on the root link (or, if a URDF joint
has that name, the first free one of ``floating_base_1``, ``floating_base_2``, ...)."""


class URDFLimitsWarning(UserWarning):
    """Revolute or prismatic joints whose ``<limit>`` gives no range are unlimited, as MuJoCo
    compiles them: no ``<limit>``, no ``lower`` or no ``upper``, or ``lower >= upper``
    (``lower > upper`` is Bullet's way to say "no limit")."""


WORLD_LINK = "world"
"""A root link of this name is the world frame itself (as in ROS and MuJoCo), not a body."""

# MuJoCo refuses a joint axis whose squared length is below this ("axis too small"); so do we.
_MIN_AXIS_SQUARED = 1e-14
_MOVING: dict[str, TreeJointType] = {
    "revolute": "revolute",
    "continuous": "revolute",
    "prismatic": "prismatic",
    "floating": "free",
    "spherical": "ball",
}
_URDF_TYPES = (*_MOVING, "fixed", "planar")
# the joints whose <axis> poekin reads
_AXIS_TYPES = ("revolute", "continuous", "prismatic")
# a joint's elements that poekin reads, which URDF allows once (MuJoCo refuses a repeat)
_AT_MOST_ONCE = ("parent", "child", "origin", "axis", "limit", "mimic")
# the numbers poekin reads: (element, attribute) -> what they are
_NUMBERS = {
    ("origin", "xyz"): "x y z",
    ("origin", "rpy"): "roll pitch yaw",
    ("axis", "xyz"): "x y z",
    ("limit", "lower"): "lower",
    ("limit", "upper"): "upper",
    ("mimic", "multiplier"): "multiplier",
    ("mimic", "offset"): "offset",
    ("mass", "value"): "mass",
}
# xacro's substitutions, which xacro's output no longer has
_XACRO_SUBSTITUTION = re.compile(
    r"\$\((?:find|optenv|env|arg|eval|dirname|anon)\b[^)]*\)?|\$\{[^}]*\}?"
)
# a finite decimal number, as MuJoCo and urdfdom (Pinocchio) read them
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


def tree_from_urdf(
    path: str | os.PathLike[str], *, floating_base: bool = False, robot: str = ""
) -> Tree:
    """The kinematic tree of a URDF file: every link a body, every moving joint a joint.

    Bodies are the links depth first from the root, a link's children in the order of their
    ``<joint>`` elements in the file: the order MuJoCo gives the same URDF. ``qpos`` is::

        qpos = [floating_base (x y z qw qx qy qz, with floating_base=True),
                the revolute, continuous, prismatic (1 each), spherical (qw qx qy qz)
                and floating (7) joints in body order, mimic followers left out]

    :attr:`Tree.joint_names` lists every joint, followers included, and :attr:`Tree.qpos_adr`
    where each one's value is (a follower: its leader's, whether the leader comes before or
    after it). A follower of a follower is tied to the independent joint at the end of the
    chain (multipliers and offsets composed).

    Args:
        path: the ``.urdf`` file.
        floating_base: put a free joint on the root link, so ``qpos`` starts with its world
            position and orientation. It is named ``"floating_base"``, or, if a URDF joint
            (of any type) has that name, the first free one of ``"floating_base_1"``,
            ``"floating_base_2"``, ...: ``tree.joint_names[0]``.
        robot: a label stored in the tree; default: the URDF's ``<robot name>``.

    Warns:
        URDFLimitsWarning: revolute or prismatic joints whose ``<limit>`` gives no range
            (see the module's docstring) are unlimited, as in MuJoCo; one warning names them.

    Raises:
        MissingExtraError: yourdfpy is not installed (the extra ``poekin[urdf]``).
        URDFError: the file is missing, not XML, not a URDF, or an unexpanded xacro file; a
            malformed joint (numbers, repeated elements); its links do not form one tree; a
            planar joint, a floating joint below the root, a zero axis, or a mimic of an
            unknown, fixed or cyclic joint.
    """
    where = os.fspath(path)
    urdf_robot = parse_urdf(where)
    link_names = [link.name for link in urdf_robot.links]
    parent_joint = _parent_joints(urdf_robot.joints, link_names, where)
    root = _root_link(link_names, parent_joint, where)
    order = _body_order(root, urdf_robot.joints, link_names, where)
    if root == WORLD_LINK:
        if floating_base:
            raise URDFError(
                f"{where}: the root link is 'world', which fixes the robot to the world; "
                "drop floating_base, or remove the 'world' link to let the robot float"
            )
        order = order[1:]
    base = _free_name(FLOATING_BASE, [j.name for j in urdf_robot.joints]) if floating_base else ""
    parents, poses, joints = _bodies(order, parent_joint, base, where)
    names = [name for name, _, _, _ in joints]
    urdf_joints = [joint for _, _, _, joint in joints]
    limits = [_limits(joint) for joint in urdf_joints]
    unused = [(name, why) for name, (_, why) in zip(names, limits, strict=True) if why]
    if unused:
        warnings.warn(_limits_note(where, unused), URDFLimitsWarning, stacklevel=2)
    body_mass, body_com = _inertials(urdf_robot.links, order)
    try:
        return Tree(
            body_names=tuple(order),
            body_parents=parents,
            body_pos=poses[:, :3, 3],
            body_rot=poses[:, :3, :3],
            joint_names=tuple(names),
            joint_types=tuple(kind for _, kind, _, _ in joints),
            joint_bodies=np.array([b for _, _, b, _ in joints], dtype=np.intp),
            joint_axes=np.array([_axis(joint, where) for joint in urdf_joints]).reshape(-1, 3),
            joint_anchors=np.zeros((len(joints), 3)),
            joint_refs=np.zeros(len(joints)),
            joint_limits=np.array([lower_upper for lower_upper, _ in limits]).reshape(-1, 2),
            mimics=_mimics(urdf_joints, urdf_robot.joints, where),
            robot=robot or urdf_robot.name,
            body_mass=body_mass,
            body_com=body_com,
            joint_velocity_limits=np.array([_speed(joint) for joint in urdf_joints]),
            _source_file=os.path.abspath(where),
        )
    except InputError as exc:  # what Tree refuses: a guard, as the checks above catch all known
        raise URDFError(f"{where}: {exc}") from exc


def _inertials(links: Sequence[Any], order: list[str]) -> tuple[FloatArray, FloatArray]:
    """Each body's mass ``(nb,)`` and centre of mass in its frame ``(nb, 3)``: its link's
    ``<inertial>`` ``<mass value>`` and ``<origin xyz>`` (0 without them), checked by
    :func:`_check_inertial`."""
    inertial = {link.name: link.inertial for link in links}
    mass, com = np.zeros(len(order)), np.zeros((len(order), 3))
    for b, name in enumerate(order):
        found = inertial[name]
        if found is not None:
            mass[b] = found.mass
            if found.origin is not None:
                com[b] = found.origin[:3, 3]
    return mass, com


def _free_name(name: str, taken: list[str]) -> str:
    """``name``, or the first of ``name_1``, ``name_2``, ... that is not ``taken``."""
    free, n = name, 0
    while free in taken:
        n += 1
        free = f"{name}_{n}"
    return free


def _bodies(
    order: list[str], parent_joint: dict[str, Any], floating_base: str, where: str
) -> tuple[IntArray, FloatArray, list[tuple[str, TreeJointType, int, Any]]]:
    """Parent indices ``(nb,)`` (-1: the world), poses in the parent ``(nb, 4, 4)``, and the
    tree joints as ``(name, type, body, URDF joint or None for the floating base)``, with a
    free joint named ``floating_base`` on the root link unless that is empty."""
    body_index = {name: b for b, name in enumerate(order)}
    poses = np.tile(np.eye(4), (len(order), 1, 1))
    parents = np.full(len(order), -1, dtype=np.intp)
    joints: list[tuple[str, TreeJointType, int, Any]] = []
    for b, link in enumerate(order):
        joint = parent_joint.get(link)
        if joint is None:
            if floating_base:
                joints.append((floating_base, "free", b, None))
            continue
        parents[b] = body_index.get(joint.parent, -1)  # the 'world' link is no body
        if joint.origin is not None:
            poses[b] = joint.origin
        kind = _tree_joint_type(joint, where)
        if kind is not None:
            joints.append((joint.name, kind, b, joint))
    return parents, poses, joints


def parse_urdf(path: str, *, visuals: bool = False) -> Any:
    """The ``yourdfpy.Robot`` of the URDF at ``path``, once the file is checked
    (:func:`_check_structure`), parsed from what poekin reads only (:func:`_keep_kinematics`),
    or with ``visuals`` from all of it (links' visual geometry and materials, for drawing)."""
    from poekin._extras import require

    if not os.path.isfile(path):  # said first: installing yourdfpy would not help
        raise URDFError(f"{path}: no such URDF file; check the path")
    yourdfpy = require("yourdfpy", "urdf", f"reading {os.path.basename(path)}")
    try:
        text = _xml_text(pathlib.Path(path).read_bytes())
    except OSError as exc:
        raise URDFError(f"{path}: cannot read the URDF file ({exc.strerror})") from exc
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        if b"<xacro:" in text:  # the xacro namespace is not even declared
            raise URDFError(_xacro_message(path, "<xacro:...> elements")) from exc
        raise URDFError(f"{path}: not well-formed XML ({exc}); fix the file") from exc
    _check_structure(root, path)
    if not visuals:
        _keep_kinematics(root)
    try:
        urdf = yourdfpy.URDF.load(
            io.BytesIO(ET.tostring(root)),
            build_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
        )
    except (ValueError, TypeError, KeyError, AttributeError, IndexError) as exc:
        raise URDFError(f"{path}: malformed URDF ({type(exc).__name__}: {exc})") from exc
    return urdf.robot


def _keep_kinematics(root: ET.Element) -> None:
    """Remove from ``root`` all that poekin does not read: links' contents but their
    ``<inertial>``'s ``<origin>`` and ``<mass>`` (the inertia tensor and geometry, whose flaws
    MuJoCo and Pinocchio may let pass or not), joints' elements other than those
    :func:`_check_joint` checks, and other top-level elements (materials, transmissions...)."""
    for elem in list(root):
        if elem.tag not in ("link", "joint"):
            root.remove(elem)
            continue
        for child in list(elem):
            if elem.tag == "link" and child.tag == "inertial":
                for part in list(child):
                    if part.tag not in ("origin", "mass"):
                        child.remove(part)
            elif elem.tag == "link" or child.tag not in _AT_MOST_ONCE:
                elem.remove(child)


def _xml_text(data: bytes) -> bytes:
    """The file's bytes, with blank space before its ``<?xml ...?>`` declaration moved after it,
    where XML allows it (and a UTF-8 byte order mark before the space dropped): MuJoCo's and
    Pinocchio's XML reader (tinyxml2) accept such files, Python's (expat) does not. Every line
    keeps its number, so parse errors point at the right one."""
    body = data.removeprefix(b"\xef\xbb\xbf")
    start = len(body) - len(body.lstrip())
    if start == 0 or not re.match(rb"<\?xml\s", body[start:]):
        return data
    end = body.find(b"?>", start) + 2
    return body[start:end] + body[:start] + body[end:] if end > 1 else data


def _check_structure(root: ET.Element, path: str) -> None:
    """What poekin reads of the file, checked before yourdfpy reads it (which would fail with a
    bare KeyError, or take the first of several elements or numbers): required names and
    attributes; in each joint, one ``<parent>`` and one ``<child>``, at most one ``<origin>``,
    ``<axis>``, ``<limit>`` and ``<mimic>``, and their numbers; each link's ``<inertial>``
    (:func:`_check_inertial`). The rest of links' contents (inertia tensors, geometry) is not
    read, so not checked."""
    if root.tag != "robot":
        hint = "; load an MJCF file with poekin.load_tree" if root.tag == "mujoco" else ""
        raise URDFError(f"{path}: not a URDF: the root element is <{root.tag}>, not <robot>{hint}")
    found = _xacro_trace(root)
    if found:
        raise URDFError(_xacro_message(path, found))
    for elem in [root, *root.findall("link")]:
        if not elem.get("name"):
            raise URDFError(f"{path}: a <{elem.tag}> has no 'name' attribute; add it")
    for link in root.findall("link"):
        _check_inertial(link, path)
    for joint in root.findall("joint"):
        _check_joint(joint, path)


def _xacro_trace(root: ET.Element) -> str:
    """The first sign that ``root`` is xacro, not URDF, in words (empty if none): an element or
    attribute in the xacro namespace, or a substitution (``$(find ...)``, ``${...}``) in an
    attribute or text of a link or joint. The namespace declared on ``<robot>`` is no sign
    (xacro's output keeps it), nor is a substitution in what only other tools read
    (``<gazebo>``, ``<ros2_control>``...)."""
    read = [root, *(e for top in root if top.tag in ("link", "joint") for e in top.iter())]
    for elem in root.iter():
        namespace, _, tag = elem.tag.rpartition("}")
        if "xacro" in namespace:
            return f"<xacro:{tag}>"
        for key in elem.attrib:
            namespace, _, attribute = key.rpartition("}")
            if "xacro" in namespace:
                return f"the attribute xacro:{attribute} of <{tag}>"
    for elem in read:
        for attribute, value in elem.attrib.items():
            match = _XACRO_SUBSTITUTION.search(value)
            if match:
                return f"{match.group()} in <{elem.tag} {attribute}>"
        match = _XACRO_SUBSTITUTION.search(elem.text or "")
        if match:
            return f"{match.group()} in <{elem.tag}>"
    return ""


def _xacro_message(path: str, found: str) -> str:
    """The error for a xacro file at ``path`` in which ``found`` was found."""
    stem = os.path.basename(path)
    for suffix in (".xacro", ".urdf"):
        stem = stem.removesuffix(suffix)
    expanded = f"{stem}.urdf" if path.endswith(".xacro") else f"{stem}_expanded.urdf"
    return (
        f"{path}: a xacro file, not URDF yet (it has {found}); expand it first with ROS's "
        f"xacro: xacro {path} > {expanded}"
    )


def _check_joint(joint: ET.Element, path: str) -> None:
    """One ``<joint>`` element: see :func:`_check_structure`."""
    name = joint.get("name")
    if not name:
        raise URDFError(f"{path}: a <joint> has no 'name' attribute; add it")
    kind = joint.get("type")
    if not kind:
        raise URDFError(f"{path}: joint {name!r} has no 'type' attribute; add it")
    where = f"joint {name!r}"
    for tag in _AT_MOST_ONCE:
        found = joint.findall(tag)
        if len(found) > 1:
            raise URDFError(
                f"{path}: joint {name!r} has {len(found)} <{tag}> elements; keep one (MuJoCo "
                "refuses such a file, other readers take the first)"
            )
    for tag in ("parent", "child"):
        elem = joint.find(tag)
        if elem is None or not elem.get("link"):
            raise URDFError(f"{path}: joint {name!r} has no <{tag} link=...>; add it")
    origin = joint.find("origin")
    if origin is not None:
        _check_numbers(origin, "xyz", where, path)
        _check_numbers(origin, "rpy", where, path)
    axis = joint.find("axis")
    if axis is not None and kind in _AXIS_TYPES:
        if axis.get("xyz") is None:
            raise URDFError(
                f'{path}: joint {name!r}: <axis> has no xyz; give <axis xyz="x y z">, or remove '
                "<axis> for the default 1 0 0"
            )
        _check_numbers(axis, "xyz", where, path)
    limit = joint.find("limit")
    if limit is not None:
        _check_numbers(limit, "lower", where, path)
        _check_numbers(limit, "upper", where, path)
    mimic = joint.find("mimic")
    if mimic is not None:
        if not mimic.get("joint"):
            raise URDFError(
                f"{path}: joint {name!r}: <mimic> has no joint; name the joint it follows: "
                '<mimic joint="...">'
            )
        _check_numbers(mimic, "multiplier", where, path)
        _check_numbers(mimic, "offset", where, path)


def _check_inertial(link: ET.Element, path: str) -> None:
    """A link's ``<inertial>``, if it has one: only one, with at most one ``<origin>`` and its
    numbers, and one ``<mass value>``, a finite number ``>= 0`` (what poekin reads of it)."""
    where = f"link {link.get('name')!r}"
    inertials = link.findall("inertial")
    if len(inertials) > 1:
        raise URDFError(
            f"{path}: {where} has {len(inertials)} <inertial> elements; keep one (MuJoCo "
            "refuses such a file, other readers take the first)"
        )
    if not inertials:
        return
    inertial = inertials[0]
    for tag in ("origin", "mass"):
        found = inertial.findall(tag)
        if len(found) > 1:
            raise URDFError(
                f"{path}: {where}: <inertial> has {len(found)} <{tag}> elements; keep one"
            )
    origin = inertial.find("origin")
    if origin is not None:
        _check_numbers(origin, "xyz", where, path)
        _check_numbers(origin, "rpy", where, path)
    mass = inertial.find("mass")
    if mass is None or mass.get("value") is None:
        raise URDFError(
            f'{path}: {where}: <inertial> has no <mass value="...">; give the link\'s mass '
            "(kg), as MuJoCo and urdfdom require, or remove <inertial> for a massless link"
        )
    _check_numbers(mass, "value", where, path)
    if float(mass.get("value", "0")) < 0:
        raise URDFError(
            f'{path}: {where}: <mass value="{mass.get("value")}"> is negative; give a mass '
            ">= 0 (kg)"
        )


def _check_numbers(elem: ET.Element, attribute: str, where: str, path: str) -> None:
    """``elem``'s ``attribute``, if given, is as many finite numbers as URDF says; ``where``
    names the element's joint or link in messages."""
    text = elem.get(attribute)
    if text is None:
        return
    meaning = _NUMBERS[elem.tag, attribute]
    count = len(meaning.split())
    words = text.split()
    given = f'{path}: {where}: <{elem.tag} {attribute}="{text}">'
    fix = f"give {count} numbers ({meaning})" if count > 1 else "give one number"
    bad = next(
        (word for word in words if not _NUMBER.fullmatch(word) or not math.isfinite(float(word))),
        None,
    )
    if bad is not None:
        raise URDFError(f"{given}: {bad!r} is not a finite number; {fix}")
    if len(words) != count:
        raise URDFError(f"{given} has {len(words)} numbers; {fix}")


def _parent_joints(joints: Sequence[Any], links: list[str], where: str) -> dict[str, Any]:
    """Each child link's joint; every joint joins known links, no link has two parents."""
    if len(set(links)) < len(links):
        twice = sorted({name for name in links if links.count(name) > 1})
        raise URDFError(f"{where}: links named more than once: {twice}; rename them")
    names = [joint.name for joint in joints]
    if len(set(names)) < len(names):
        twice = sorted({name for name in names if names.count(name) > 1})
        raise URDFError(f"{where}: joints named more than once: {twice}; rename them")
    parent_joint: dict[str, Any] = {}
    for joint in joints:
        for link in (joint.parent, joint.child):
            if link not in links:
                raise URDFError(
                    f"{where}: joint {joint.name!r} names link {link!r}, which is not defined: "
                    f"{did_you_mean(link, links)}"
                )
        if joint.child in parent_joint:
            raise URDFError(
                f"{where}: link {joint.child!r} is the child of both joints "
                f"{parent_joint[joint.child].name!r} and {joint.name!r}; a URDF is a tree"
            )
        parent_joint[joint.child] = joint
    return parent_joint


def _root_link(links: list[str], parent_joint: dict[str, Any], where: str) -> str:
    """The only link that is no joint's child."""
    if not [name for name in links if name != WORLD_LINK]:
        raise URDFError(
            f"{where}: no link to pose (a link named 'world' is the world itself); add the "
            "robot's <link> and <joint> elements"
        )
    roots = [name for name in links if name not in parent_joint]
    if len(roots) == 1:
        return roots[0]
    if roots:
        raise URDFError(
            f"{where}: {len(roots)} root links (no joint's child): {roots}; a URDF has one, "
            "so join the others to it with joints"
        )
    raise URDFError(f"{where}: no root link: the joints form a cycle through every link")


def _body_order(root: str, joints: Sequence[Any], links: list[str], where: str) -> list[str]:
    """Links depth first from ``root``, children in file order of their joints."""
    children: dict[str, list[str]] = {name: [] for name in links}
    for joint in joints:
        children[joint.parent].append(joint.child)
    order: list[str] = []
    stack = [root]
    while stack:
        link = stack.pop()
        order.append(link)
        stack.extend(reversed(children[link]))
    if len(order) < len(links):
        cut = [name for name in links if name not in set(order)]
        raise URDFError(
            f"{where}: links {cut} are not reachable from the root link {root!r}: their joints "
            "form a cycle; a URDF is a tree"
        )
    return order


def _tree_joint_type(joint: Any, where: str) -> TreeJointType | None:
    """The tree joint a URDF joint becomes (None: fixed); refuses planar and deep floating."""
    if joint.type not in _URDF_TYPES:
        raise URDFError(
            f"{where}: joint {joint.name!r} has type {joint.type!r}; a URDF joint is one of "
            f"{list(_URDF_TYPES)}"
        )
    if joint.type == "planar":
        raise URDFError(
            f"{where}: joint {joint.name!r} is planar (3 degrees of freedom in a plane), which "
            "the tree's hinge/slide/ball/free joints cannot hold as one joint (MuJoCo splits it "
            "into _TX, _TY slides and an _RZ hinge); model it as two prismatic joints and a "
            "revolute joint through intermediate links"
        )
    if joint.type == "floating" and joint.parent != WORLD_LINK:
        raise URDFError(
            f"{where}: floating joint {joint.name!r} hangs below link {joint.parent!r}; a free "
            "joint must join a link to the world: make its parent the root link 'world', or "
            "remove it and pass floating_base=True"
        )
    return _MOVING.get(joint.type)


def _axis(joint: Any | None, where: str) -> tuple[float, float, float]:
    """Unit joint axis in the child link frame: ``<axis xyz>`` (default ``1 0 0``) over its norm."""
    if joint is None or joint.type not in _AXIS_TYPES:  # floating, spherical: no axis
        return (1.0, 0.0, 0.0)
    x, y, z = (float(v) for v in joint.axis)  # 3 finite numbers: _check_joint
    squared = x * x + y * y + z * z
    if squared < _MIN_AXIS_SQUARED:
        raise URDFError(
            f"{where}: joint {joint.name!r} has a zero <axis xyz> (length "
            f"{math.sqrt(squared):.3g}, under MuJoCo's 1e-7); give the direction it moves in"
        )
    norm = math.sqrt(squared)
    return (x / norm, y / norm, z / norm)


def _limits(joint: Any | None) -> tuple[tuple[float, float], str]:
    """``(lower, upper)`` of a joint as MuJoCo compiles its ``<limit>``, and why a revolute or
    prismatic joint's limit is not used (empty if it is, and for other joints).

    MuJoCo limits a hinge or slide to ``[lower, upper]`` when both are given and
    ``lower < upper``; otherwise it leaves the joint unlimited.
    """
    unlimited = (-math.inf, math.inf)
    if joint is None or joint.type not in ("revolute", "prismatic"):
        return unlimited, ""
    limit = joint.limit
    if limit is None:
        return unlimited, "no <limit>"
    lower, upper = limit.lower, limit.upper
    if lower is None and upper is None:
        return unlimited, "<limit> without lower and upper, which the URDF spec reads as 0 0"
    if lower is None or upper is None:
        return unlimited, f"<limit> with {'upper' if lower is None else 'lower'} only"
    given = f'<limit lower="{lower:g}" upper="{upper:g}">'
    if lower > upper:
        return unlimited, f'{given}, Bullet\'s "no limit"'
    if lower == upper:
        return unlimited, given
    return (float(lower), float(upper)), ""


def _speed(joint: Any | None) -> float:
    """A revolute or prismatic joint's ``<limit velocity>`` (rad/s, m/s), ``inf`` where it
    gives none or one that is not > 0."""
    limit = None if joint is None else joint.limit
    velocity = None if limit is None else getattr(limit, "velocity", None)
    if velocity is None or not math.isfinite(float(velocity)) or float(velocity) <= 0:
        return math.inf
    return float(velocity)


def _limits_note(where: str, unused: list[tuple[str, str]]) -> str:
    """The note that the limits of the ``(joint, why)`` in ``unused`` are not used."""
    listed = 3
    shown = "; ".join(f"{name!r}: {why}" for name, why in unused[:listed])
    more = f"; and {len(unused) - listed} more" if len(unused) > listed else ""
    joints = "1 joint is" if len(unused) == 1 else f"{len(unused)} joints are"
    return f"{where}: {joints} unlimited, as in MuJoCo ({shown}{more})"


def _mimics(
    urdf_joints: list[Any | None], all_joints: Sequence[Any], where: str
) -> tuple[Mimic | None, ...]:
    """One entry per tree joint (``urdf_joints``; None: the floating base): for a follower,
    its independent leader with the multipliers and offsets along the way composed."""
    hinges = {j.name: j for j in urdf_joints if j is not None and j.type in _AXIS_TYPES}
    out: list[Mimic | None] = []
    for joint in urdf_joints:
        if joint is None or joint.mimic is None:
            out.append(None)
            continue
        multiplier, offset, leader = 1.0, 0.0, joint
        seen = [joint.name]
        while leader.mimic is not None:
            m = leader.mimic
            if leader.name not in hinges or m.joint not in hinges:
                raise URDFError(f"{where}: {_bad_mimic(leader.name, m.joint, all_joints)}")
            offset += multiplier * (0.0 if m.offset is None else float(m.offset))
            multiplier *= 1.0 if m.multiplier is None else float(m.multiplier)
            leader = hinges[m.joint]
            if leader.name in seen:
                raise URDFError(
                    f"{where}: mimic joints form a cycle: {' -> '.join([*seen, leader.name])}; "
                    "one of them must move on its own"
                )
            seen.append(leader.name)
        out.append(Mimic(leader.name, multiplier, offset))
    return tuple(out)


def _bad_mimic(follower: str, leader: str, all_joints: Sequence[Any]) -> str:
    """Why ``follower`` cannot mimic ``leader``: one of them is no hinge/slide, or no joint."""
    types = {j.name: j.type for j in all_joints}
    if leader not in types:
        return f"joint {follower!r} mimics {leader!r}, which is not a joint: " + did_you_mean(
            leader, list(types)
        )
    odd = follower if types[follower] not in _AXIS_TYPES else leader
    return (
        f"joint {follower!r} mimics {leader!r}, but {odd!r} is a {types[odd]} joint; "
        "mimic joints must be revolute, continuous or prismatic"
    )
