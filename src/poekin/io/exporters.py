"""Write a chain as other tools read it: UR's ``kinematics:`` YAML, or a URDF. ``poekin export``.

>>> chain = poekin.load_params("my_robot.json")   # e.g. what poekin calibrate wrote
>>> poekin.export(chain, "ur-yaml", "my_robot_kinematics.yaml")   # for ur_description
>>> poekin.export(chain, "urdf", "my_robot.urdf")                  # for ROS, Pinocchio, MuJoCo

* ``"ur-yaml"``: the six segment origins ``x, y, z, roll, pitch, yaw`` of UR's calibration
  file, in the layout of ur_description's ``default_kinematics.yaml``, which ur_description
  (``kinematics_params_file:=``) and ``poekin.load_params`` read back. Only a UR arm in UR's
  ``base`` frame can be written so (:func:`poekin.io.ur_kinematics.ur_origins`); its end frame is
  ``tool0`` on joint 6's axis, and what lies beyond it (a tool, or a calibrated flange's offset
  off the axis) is returned as ``tcp``, the controller's TCP setting.
* ``"urdf"``: one link per joint, its frame on the joint's axis line (z along the axis), and
  the end frame a fixed link; joint limits carried over (``continuous`` for an unlimited revolute
  joint). A ``<mujoco>`` element lets MuJoCo compile it as it is (no fused links, a minimal
  mass for the massless ones); URDF readers ignore it.

Numbers are written with 17 significant digits: the same float64 numbers read back. Lengths
are metres, angles radians. The ``*_text`` functions do no I/O; :func:`export` writes.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pathlib
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.chain import Chain
from poekin.dh import DHTable, joint_lines
from poekin.errors import InputError, did_you_mean
from poekin.io.ur_kinematics import (
    UR_ORIGIN_KEYS,
    UR_SEGMENTS,
    URYamlOrder,
    check_order,
    ur_origins,
)

__all__ = ["EXPORT_FORMATS", "ExportFormat", "Exported", "export", "ur_yaml_text", "urdf_text"]

FloatArray = NDArray[np.float64]
ExportFormat = Literal["ur-yaml", "urdf"]
#: What :func:`export` writes, and the file name endings each takes.
EXPORT_FORMATS: dict[str, tuple[str, ...]] = {"ur-yaml": (".yaml", ".yml"), "urdf": (".urdf",)}
# Values smaller than this (m, rad) are rounding (a 6e-17 cosine): written as 0.
_ROUNDING = 1e-15


@dataclasses.dataclass(frozen=True)
class Exported:
    """What :func:`export` wrote.

    Attributes:
        path: the file.
        to: its format, a key of :data:`EXPORT_FORMATS`.
        tcp: ``(4, 4)`` ``T_tool0_frame``: the chain's end frame seen from the file's ``tool0``
            (``"ur-yaml"``; the controller's TCP setting), the identity for a URDF.
        model: the UR model the file is of (``"ur5e"``; ``"ur-yaml"`` only, else ``""``).
    """

    path: pathlib.Path
    to: ExportFormat
    tcp: FloatArray
    model: str


def _number(x: float) -> str:
    """``x`` as text that reads back to the same float64, a float for YAML 1.1 too (PyYAML
    reads ``1e-20``, without a dot, as text)."""
    value = float(x)
    if abs(value) < _ROUNDING:
        return "0.0"
    text = repr(value)
    mantissa, e, exponent = text.partition("e")
    if e and "." not in mantissa:
        text = f"{mantissa}.0e{exponent}"
    return text


def ur_yaml_text(
    chain: Chain, *, order: URYamlOrder = "description"
) -> tuple[str, FloatArray, str]:
    """UR's ``kinematics:`` YAML of a UR arm's chain (see the module docstring).

    Args:
        chain: six revolute joints in UR's ``base`` frame.
        order: how the file's angles compose: ``"description"`` (``Rz Ry Rx``, as ur_description
            reads them) or ``"controller"`` (``Rx Ry Rz``, as ur_calibration writes them).

    Returns:
        ``(text, tcp, model)``: the file's text; ``T_tool0_frame`` ``(4, 4)``; the UR model.

    Raises:
        InputError: the chain is not a UR arm in UR's base frame.
    """
    origins, tcp, model = ur_origins(chain, order=order)
    digest = hashlib.sha256(origins.tobytes()).hexdigest()[:16]
    composed = (
        "Rz(yaw) Ry(pitch) Rx(roll) (as ur_description reads them)"
        if order == "description"
        else "Rx(roll) Ry(pitch) Rz(yaw) (as ur_calibration writes them)"
    )
    lines = [
        f"# {chain.robot or 'a UR arm'} ({model}) to {chain.frame!r}, written by poekin export",
        f"# x y z in metres; roll pitch yaw in radians, R = {composed}",
    ]
    if not np.allclose(tcp, np.eye(4), rtol=0.0, atol=1e-12):
        x, y, z = tcp[:3, 3]
        rx, ry, rz = np.asarray(lie.log_so3(tcp[:3, :3]), dtype=np.float64)
        lines.append(
            f"# the end frame {chain.frame!r} from tool0 (the controller's TCP): x y z "
            f"{_number(x)} {_number(y)} {_number(z)} m, rx ry rz {_number(rx)} {_number(ry)} "
            f"{_number(rz)} rad (a rotation vector)"
        )
    lines.append("kinematics:")
    for name, row in zip(UR_SEGMENTS, origins, strict=True):
        lines.append(f"  {name}:")
        lines += [f"    {k}: {_number(v)}" for k, v in zip(UR_ORIGIN_KEYS, row, strict=True)]
    lines.append(f"  hash: poekin_{digest}")
    return "\n".join(lines) + "\n", tcp, model


def _link_names(chain: Chain) -> tuple[str, list[str]]:
    """The root link's name and one link name per joint, none equal to the end frame's or each
    other."""
    taken = {chain.frame}

    def fresh(name: str) -> str:
        candidate, k = name, 1
        while candidate in taken:
            candidate, k = f"{name}_{k}", k + 1
        taken.add(candidate)
        return candidate

    root = fresh("base")
    links = [
        fresh(name.removesuffix("_joint") + "_link" if name.endswith("_joint") else name + "_link")
        for name in chain.joint_names
    ]
    return root, links


def _origin(T: FloatArray) -> str:
    xyz = " ".join(_number(v) for v in T[:3, 3])
    rpy = " ".join(_number(v) for v in np.asarray(lie.rotation_to_rpy(T[:3, :3])))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _joint_kind(chain: Chain, i: int) -> tuple[str, str]:
    """URDF's joint type and its ``<limit>`` element (or "") for joint ``i``."""
    assert chain.limits is not None
    lower, upper = (float(v) for v in chain.limits[i])
    name = chain.joint_names[i]
    revolute = chain.joint_types[i] == "revolute"
    if revolute and np.isinf(lower) and np.isinf(upper):
        return "continuous", ""
    if np.isinf(lower) or np.isinf(upper):
        what = "a revolute joint takes both limits or none (continuous)"
        if not revolute:
            what = "a prismatic joint needs both limits"
        raise InputError(
            f"joint {name!r} has limits [{lower:g}, {upper:g}]: in a URDF {what}; give the chain "
            "finite limits (Chain(..., limits=...))"
        )
    limit = f'<limit lower="{_number(lower)}" upper="{_number(upper)}" effort="0" velocity="0"/>'
    return ("revolute" if revolute else "prismatic"), limit


def _escape(text: str) -> str:
    return (
        text.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;").replace(">", "&gt;")
    )


def urdf_text(chain: Chain, *, name: str | None = None) -> str:
    """A URDF of the chain (see the module docstring): link ``i``'s frame is on joint ``i``'s
    axis line, z along the axis, turned from the previous link's by the smallest rotation; the
    end frame is the fixed link ``chain.frame``.

    Args:
        chain: any serial chain of revolute and prismatic joints.
        name: the robot's name (default: ``chain.robot``, or ``"robot"``).

    Raises:
        InputError: a joint limited on one side only, or an unlimited prismatic joint (URDF
            cannot say either).
    """
    kinds = [_joint_kind(chain, i) for i in range(chain.n_joints)]
    dirs, points = joint_lines(chain)
    root, links = _link_names(chain)
    lines = [
        '<?xml version="1.0"?>',
        f"<!-- {_escape(chain.robot or 'a chain')} to {_escape(chain.frame)!r}, written by "
        "poekin export; metres, radians -->",
        f'<robot name="{_escape(name or chain.robot or "robot")}">',
        "  <mujoco>",
        '    <compiler fusestatic="false" discardvisual="false" boundmass="1e-6" '
        'boundinertia="1e-12"/>',
        "  </mujoco>",
        f'  <link name="{_escape(root)}"/>',
    ]
    previous, parent = np.eye(4), root
    for i, (kind, limit) in enumerate(kinds):
        F = np.eye(4)
        z = previous[:3, 2]
        k = np.cross(z, dirs[i])
        s = float(np.linalg.norm(k))
        turn = np.eye(3)
        if s > 0.0:
            turn = np.asarray(
                lie.exp_so3(k / s * float(np.arctan2(s, z @ dirs[i]))), dtype=np.float64
            )
        F[:3, :3] = turn @ previous[:3, :3]
        F[:3, 3] = points[i]
        joint = _escape(chain.joint_names[i])
        lines += [
            f'  <link name="{_escape(links[i])}"/>',
            f'  <joint name="{joint}" type="{kind}">',
            f'    <parent link="{_escape(parent)}"/>',
            f'    <child link="{_escape(links[i])}"/>',
            f"    {_origin(np.asarray(lie.inverse(previous), dtype=np.float64) @ F)}",
            '    <axis xyz="0 0 1"/>',
            *([f"    {limit}"] if limit else []),
            "  </joint>",
        ]
        previous, parent = F, links[i]
    fixed = f"{chain.frame}_fixed"
    while fixed in chain.joint_names:
        fixed += "_"
    lines += [
        f'  <link name="{_escape(chain.frame)}"/>',
        f'  <joint name="{_escape(fixed)}" type="fixed">',
        f'    <parent link="{_escape(parent)}"/>',
        f'    <child link="{_escape(chain.frame)}"/>',
        f"    {_origin(np.asarray(lie.inverse(previous), dtype=np.float64) @ chain.home)}",
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines) + "\n"


def check_export(to: str, path: str | os.PathLike[str], *, force: bool = False) -> pathlib.Path:
    """Refuse an unknown format, a file name ending that is not the format's, or an existing
    file (without ``force``), before anything is computed or written."""
    from poekin.io.fileio import check_new_file

    if to not in EXPORT_FORMATS:
        raise InputError(f"unknown export format {to!r}: {did_you_mean(to, EXPORT_FORMATS)}")
    p = pathlib.Path(path)
    suffixes = EXPORT_FORMATS[to]
    if p.suffix.lower() not in suffixes:
        raise InputError(
            f"{p}: a {to} file ends in {' or '.join(suffixes)}, got {p.suffix or 'no suffix'!r}"
        )
    return check_new_file(p, f"{to} file", force=force)


def export(
    params: Chain | DHTable,
    to: ExportFormat,
    path: str | os.PathLike[str],
    *,
    force: bool = False,
    ur_yaml_order: URYamlOrder = "description",
) -> Exported:
    """Write ``params`` as ``to`` (a key of :data:`EXPORT_FORMATS`) to ``path``.

    Args:
        params: a chain, or a DH table (its chain is written).
        to: ``"ur-yaml"`` (UR's ``kinematics:`` file) or ``"urdf"``.
        path: the file to write: ``.yaml``/``.yml`` or ``.urdf``.
        force: replace an existing file.
        ur_yaml_order: ``"ur-yaml"``: how the angles compose (``"description"`` as
            ur_description reads them, ``"controller"`` as ur_calibration writes them).

    Returns:
        What was written (:class:`Exported`), the TCP that a ``"ur-yaml"`` file leaves out.

    Raises:
        InputError: an unknown format, a suffix not the format's, an existing file without
            ``force``, or a chain the format cannot hold (not a UR arm for ``"ur-yaml"``);
            nothing is written then.
    """
    from poekin.io.fileio import write_text

    check_order(ur_yaml_order)
    p = check_export(to, path, force=force)
    if not isinstance(params, Chain | DHTable):
        raise InputError(
            f"export takes a Chain or a DHTable (poekin.load_params reads a file), not a "
            f"{type(params).__name__}"
        )
    chain = params.to_chain() if isinstance(params, DHTable) else params
    if to == "ur-yaml":
        text, tcp, model = ur_yaml_text(chain, order=ur_yaml_order)
    else:
        text, tcp, model = urdf_text(chain), np.eye(4), ""
    write_text(p, text, what=f"{to} file")
    return Exported(p, to, tcp, model)
