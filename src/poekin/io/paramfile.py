"""Parameter files: read a DH table or a PoE parameter set from JSON or YAML, or by name.

Accepted shapes (JSON shown; YAML holds the same structure)::

    # a DH table, exactly what DHTable.describe() writes (extra keys such as "notes" ignored)
    {"convention": "standard",
     "rows": [{"a": 0, "alpha": 1.5708, "d": 0.1625, "theta_offset": 0,
               "joint_type": "revolute", "joint": "shoulder_pan_joint"}, ...],
     "base": [[1, 0, 0, 0], ...], "tool": [[1, 0, 0, 0], ...], "frame": "flange", "robot": ""}

    # a PoE set: space-frame screws [w; v] (or "body_screws") and the home pose M
    {"screws": [[0, 0, 1, 0, 0, 0], ...], "home": [[1, 0, 0, 0.8], ...],
     "joint_names": [...], "joint_types": [...], "frame": "ee", "robot": ""}

    # exactly what Chain.describe() writes ("body_screw" ignored; "limits" optional)
    {"robot": "", "frame": "ee", "joints": [{"name": "j1", "type": "revolute",
     "screw": [0, 0, 1, 0, 0, 0], "limits": [-3.14, 3.14]}, ...], "home": [[1, 0, 0, 0.8], ...]}

    # a Universal Robots calibration, as ur_calibration writes it (see poekin.io.ur_kinematics):
    # the chain from UR's base frame to tool0
    {"kinematics": {"shoulder": {"x": 0, "y": 0, "z": 0.1625, "roll": 0, "pitch": 0, "yaw": 0},
                    "upper_arm": {...}, "forearm": {...}, "wrist_1": {...}, "wrist_2": {...},
                    "wrist_3": {...}, "hash": "calib_12788084448423163542"}}

A DH table may say ``"angle_unit": "deg"``: its ``alpha`` and ``theta_offset`` are then
degrees (lengths stay metres). Without it, angles are radians, and a table whose angles look
like degrees (beyond a full turn, e.g. ``alpha: 90``) gets a :class:`~poekin.errors.UnitWarning`.

Optional keys: ``theta_offset`` (0), ``joint_type`` (``"revolute"``), ``joint`` (``jointN``),
``base``/``tool`` (identity), ``joint_names`` (``jointN``), ``joint_types`` (revolute),
``frame`` (``"ee"``), ``robot`` (``""``). Units are metres and radians.

A PoE set's joint limits: ``joints[i].limits`` or, beside ``screws``, ``limits`` (one
``[lower, upper]`` per joint; ``null`` for no limit). A lower limit above the upper is refused,
naming the joint. A PoE set may also carry ``registration``, the pose of its base frame in the
frame that measured it (what ``poekin calibrate`` writes beside the robot in its own base frame):
``{"T_meas_base": 4x4, "std_m": [3] or null, "std_rad": [3] or null}``. The chain does not
apply it: :func:`load_registration` reads it.

Lengths no arm has are refused: a chain whose end frame is more than 20 m from one of its
revolute axes (no arm reaches that far: the longest, the ISS's Canadarm2, reaches 17.6 m; a file
in millimetres lands 1000 times too far).

This module only reads; :mod:`poekin.io.exporters` writes. Every malformed input raises
:class:`~poekin.errors.InputError` whose one-line message names the source, the place in it and
what to do.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.chain import Chain, JointType, check_pose
from poekin.dh import Convention, DHTable
from poekin.errors import InputError, UnitWarning, UnknownParamsError, did_you_mean, nearest
from poekin.io.params import PARAM_SETS, named_params
from poekin.io.ur_kinematics import (
    UR_ORIGIN_KEYS,
    UR_SEGMENTS,
    URYamlOrder,
    check_order,
    nominal_model,
    ur_chain,
)

__all__ = [
    "FILE_SUFFIXES",
    "MAX_REACH_M",
    "Registration",
    "load_params",
    "load_registration",
    "params_from_dict",
]

#: File name endings :func:`load_params` reads (case-insensitive).
FILE_SUFFIXES = (".json", ".yaml", ".yml")

FloatArray = NDArray[np.float64]
_T = TypeVar("_T")

_ROW_KEYS = ("a", "alpha", "d", "theta_offset", "joint_type", "joint")
# DH angles beyond this (rad) are more likely degrees than more than a turn.
_DEGREES_LIKELY = 2 * np.pi + 1e-9
_ROW_HINT = "each row needs a, alpha, d (theta_offset and joint_type are optional)"
_SCREW_HINT = "each screw is [w1, w2, w3, v1, v2, v3] (angular part first)"
#: The farthest (m) a parameter file's end frame may be from one of its revolute axes. No arm
#: reaches farther: industrial arms reach at most about 4.7 m, the ISS's Canadarm2 17.6 m. A file
#: in millimetres puts any arm of more than 20 mm beyond it.
MAX_REACH_M = 20.0
_NEITHER = (
    "neither a DH table (needs 'rows'), a PoE set (needs 'screws' or 'body_screws' with 'home') "
    "nor a UR calibration (needs 'kinematics')"
)


# --- small validators: each names its place ("rows[2].alpha") in the message ------------------


def _kind(x: object) -> str:
    """How a JSON/YAML value reads in an error message: ``a string ('pi/2')``, ``null``..."""
    if x is None:
        return "null"
    if isinstance(x, (bool, np.bool_)):
        return str(bool(x)).lower()
    if isinstance(x, str):
        return f"a string ({x!r:.40})"
    if isinstance(x, Mapping):
        return "an object"
    if isinstance(x, (list, tuple, np.ndarray)):
        return f"a list of {len(x)}"
    return f"{type(x).__name__} {x!r:.40}"


def _items(x: object) -> list[Any] | None:
    """``x`` as a list if it is a JSON/YAML list (or a tuple, or a numpy array); else None."""
    if isinstance(x, (list, tuple)) or (isinstance(x, np.ndarray) and x.ndim >= 1):
        return list(x)
    return None


def _number(x: object, where: str) -> float:
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise InputError(f"{where} must be a number, got {_kind(x)}{_quoted_number_hint(x)}")
    try:
        value = float(x)
    except OverflowError:
        value = float("inf")
    if not np.isfinite(value):
        what = "NaN" if np.isnan(value) else "infinite"
        raise InputError(f"{where} is {what}; every parameter must be a finite number")
    return value


def _quoted_number_hint(x: object) -> str:
    """For a string that reads as a number: how to write it so that it is one."""
    if not isinstance(x, str):
        return ""
    try:
        float(x)
    except ValueError:
        return ""
    return "; drop the quotes (YAML reads 1e-3 as text: write 1.0e-3)"


def _vector(x: object, where: str, n: int, hint: str) -> list[float]:
    items = _items(x)
    if items is None:
        raise InputError(f"{where} must be a list of {n} numbers, got {_kind(x)}; {hint}")
    if len(items) != n:
        raise InputError(f"{where} has {len(items)} numbers, expected {n}; {hint}")
    return [_number(v, f"{where}[{j}]") for j, v in enumerate(items)]


def _matrix4(x: object, where: str) -> FloatArray:
    hint = "write it as 4 rows of 4 numbers, the last row [0, 0, 0, 1]"
    rows = _items(x)
    if rows is None:
        raise InputError(f"{where} must be a 4x4 matrix, got {_kind(x)}; {hint}")
    if len(rows) != 4:
        raise InputError(f"{where} must be a 4x4 matrix, got {len(rows)} rows; {hint}")
    return np.array([_vector(r, f"{where}[{i}]", 4, hint) for i, r in enumerate(rows)])


def _string(x: object, where: str) -> str:
    if not isinstance(x, str):
        raise InputError(f"{where} must be a string, got {_kind(x)}")
    return x


def _list(x: object, where: str, what: str) -> list[Any]:
    items = _items(x)
    if items is None:
        raise InputError(f"{where} must be a list of {what}, got {_kind(x)}")
    if not items:
        raise InputError(f"{where} is empty; give one entry ({what}) per joint, base to tip")
    return items


def _mapping(x: object, where: str, what: str) -> Mapping[str, Any]:
    if not isinstance(x, Mapping):
        raise InputError(f"{where} must be an object with {what}, got {_kind(x)}")
    return x


def _unique_names(names: Sequence[str], where: str) -> None:
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise InputError(f"{where}: joint name {name!r} appears twice; joint names must differ")
        seen.add(name)


def _build(source: str, make: Callable[[], _T]) -> _T:
    """``make()``, with the source put in front of the InputError a constructor raises."""
    try:
        return make()
    except InputError as e:
        raise InputError(f"{source}: {e}") from e


# --- the two shapes ---------------------------------------------------------------------------


def _dh_table(obj: Mapping[str, Any], source: str) -> DHTable:
    if "convention" not in obj:
        raise InputError(
            f"{source}: a DH table needs 'convention': \"standard\" (Denavit-Hartenberg) or "
            '"modified" (Craig)'
        )
    convention = _string(obj["convention"], f"{source}: 'convention'")
    unit = _angle_unit(obj, source)
    rows = _list(obj["rows"], f"{source}: 'rows'", "rows {a, alpha, d, ...}")
    a, alpha, d, theta = [], [], [], []
    types: list[str] = []
    names: list[str] = []
    for i, row in enumerate(rows):
        at = f"{source}: rows[{i}]"
        row = _mapping(row, at, "a, alpha, d (theta_offset and joint_type are optional)")
        for key in row:
            if key not in _ROW_KEYS:
                close = nearest(str(key), _ROW_KEYS, cutoff=0.5)  # 'theta' -> 'theta_offset'
                hint = f" (did you mean {close!r}?)" if close else ""
                raise InputError(
                    f"{at} has an unknown key {key!r}{hint}; row keys are {', '.join(_ROW_KEYS)}"
                )
        for key in ("a", "alpha", "d"):
            if key not in row:
                raise InputError(f"{at} has no {key!r}; {_ROW_HINT}")
        a.append(_number(row["a"], f"{at}.a"))
        alpha.append(_number(row["alpha"], f"{at}.alpha"))
        d.append(_number(row["d"], f"{at}.d"))
        theta.append(_number(row.get("theta_offset", 0.0), f"{at}.theta_offset"))
        types.append(_string(row.get("joint_type", "revolute"), f"{at}.joint_type"))
        names.append(_string(row.get("joint", f"joint{i + 1}"), f"{at}.joint"))
    _unique_names(names, f"{source}: rows")
    if unit == "deg":
        alpha, theta = list(np.radians(alpha)), list(np.radians(theta))
    elif "angle_unit" not in obj:
        _note_degrees(source, alpha, theta)
    base = _matrix4(obj["base"], f"{source}: 'base'") if "base" in obj else np.eye(4)
    tool = _matrix4(obj["tool"], f"{source}: 'tool'") if "tool" in obj else np.eye(4)
    frame = _string(obj.get("frame", "ee"), f"{source}: 'frame'")
    robot = _string(obj.get("robot", ""), f"{source}: 'robot'")
    return _build(
        source,
        lambda: DHTable(
            cast(Convention, convention),  # DHTable checks it, with its own message
            np.array(a),
            np.array(alpha),
            np.array(d),
            np.array(theta),
            cast("tuple[JointType, ...]", tuple(types)),  # DHTable checks them too
            tuple(names),
            base=base,
            tool=tool,
            frame=frame,
            robot=robot,
        ),
    )


def _angle_unit(obj: Mapping[str, Any], source: str) -> str:
    """``angle_unit``: ``"rad"`` (the default) or ``"deg"`` for a DH table's alpha and
    theta_offset."""
    unit = _string(obj.get("angle_unit", "rad"), f"{source}: 'angle_unit'")
    if unit not in ("rad", "deg"):
        raise InputError(f"{source}: 'angle_unit' is {unit!r}; use 'rad' (the default) or 'deg'")
    return unit


def _note_degrees(source: str, alpha: Sequence[float], theta: Sequence[float]) -> None:
    """Warn when a DH table's angles, read as radians, look like degrees (more than a turn)."""
    for name, values in (("alpha", alpha), ("theta_offset", theta)):
        big = [(i, v) for i, v in enumerate(values) if abs(v) > _DEGREES_LIKELY]
        if big:
            i, v = big[0]
            warnings.warn(
                f"{source}: rows[{i}].{name} = {v:g} is read as radians (more than a turn); if "
                "the table's angles are degrees, add angle_unit: deg",
                UnitWarning,
                stacklevel=5,
            )
            return


def _joints_form(
    obj: Mapping[str, Any], source: str
) -> tuple[list[Any], list[Any], list[Any], list[Any]]:
    """Screws, names, types and limits (None where absent) from ``Chain.describe()``'s
    ``joints`` list."""
    joints = _list(obj["joints"], f"{source}: 'joints'", "joints {name, type, screw}")
    screws, names, types, limits = [], [], [], []
    for i, joint in enumerate(joints):
        at = f"{source}: joints[{i}]"
        joint = _mapping(joint, at, "'screw' (name, type and limits are optional)")
        if "screw" not in joint:
            raise InputError(f"{at} has no 'screw'; {_SCREW_HINT}")
        screws.append(joint["screw"])
        names.append(joint.get("name", f"joint{i + 1}"))
        types.append(joint.get("type", "revolute"))
        limits.append(joint.get("limits"))
    return screws, names, types, limits


def _bound(x: object, where: str, infinite: float) -> float:
    """One joint limit: a number, or null (or JSON's Infinity) for none."""
    if x is None:
        return infinite
    if isinstance(x, float) and x == infinite:  # JSON's Infinity, -Infinity
        return infinite
    return _number(x, where)


def _limits(raw: Sequence[Any], names: Sequence[str], where: str, source: str) -> FloatArray | None:
    """``(n, 2)`` joint limits from ``[lower, upper]`` pairs (None: the joint has none), or None
    when no joint has any. A lower limit above the upper is refused, naming the joint."""
    if all(x is None for x in raw):
        return None
    out = np.tile([-np.inf, np.inf], (len(raw), 1))
    hint = "write [lower, upper] (rad, or m for a prismatic joint), null for no limit"
    for i, pair in enumerate(raw):
        if pair is None:
            continue
        at = f"{source}: {where.format(i=i)}"
        items = _items(pair)
        if items is None or len(items) != 2:
            raise InputError(f"{at} must be [lower, upper], got {_kind(pair)}; {hint}")
        lower = _bound(items[0], f"{at}[0]", -np.inf)
        upper = _bound(items[1], f"{at}[1]", np.inf)
        if lower > upper:
            raise InputError(
                f"{source}: joint {names[i]!r} has limits [{lower:g}, {upper:g}]: the lower "
                f"limit is above the upper ({where.format(i=i)}); {hint}"
            )
        out[i] = lower, upper
    return out


def _per_joint(
    obj: Mapping[str, Any], field: str, default: list[Any], key: str, source: str
) -> list[Any]:
    """``obj[field]`` (one entry per screw in ``obj[key]``), or ``default`` if it is absent."""
    if field not in obj:
        return default
    items = _list(obj[field], f"{source}: {field!r}", "strings, one per joint")
    if len(items) != len(default):
        raise InputError(
            f"{source}: {field!r} has {len(items)} entries but {key!r} has {len(default)}; "
            "give one per joint"
        )
    return items


def _poe_chain(obj: Mapping[str, Any], source: str) -> Chain:
    if _angle_unit(obj, source) == "deg":
        raise InputError(
            f"{source}: angle_unit applies to a DH table's alpha and theta_offset; a PoE set's "
            "screws and home pose hold no angles"
        )
    if "screws" in obj and "body_screws" in obj:
        raise InputError(
            f"{source}: has both 'screws' and 'body_screws'; keep one (space or body frame)"
        )
    if "home" not in obj:
        raise InputError(
            f"{source}: a PoE set needs 'home', the 4x4 pose of the end frame at q = 0"
        )
    if "joints" in obj and "screws" not in obj and "body_screws" not in obj:
        key = "joints"
        raw, raw_names, raw_types, raw_limits = _joints_form(obj, source)
        name_at, type_at, limits_at = "joints[{i}].name", "joints[{i}].type", "joints[{i}].limits"
    else:
        key = "screws" if "screws" in obj else "body_screws"
        raw = _list(obj[key], f"{source}: {key!r}", "screws [w1, w2, w3, v1, v2, v3]")
        n = len(raw)
        raw_names = _per_joint(obj, "joint_names", [f"joint{i + 1}" for i in range(n)], key, source)
        raw_types = _per_joint(obj, "joint_types", ["revolute"] * n, key, source)
        raw_limits = _per_joint(obj, "limits", [None] * n, key, source)
        name_at, type_at, limits_at = "joint_names[{i}]", "joint_types[{i}]", "limits[{i}]"
    at = "joints[{i}].screw" if key == "joints" else key + "[{i}]"
    screws = np.array(
        [_vector(s, f"{source}: {at.format(i=i)}", 6, _SCREW_HINT) for i, s in enumerate(raw)]
    )
    names = [_string(x, f"{source}: {name_at.format(i=i)}") for i, x in enumerate(raw_names)]
    types = [_string(x, f"{source}: {type_at.format(i=i)}") for i, x in enumerate(raw_types)]
    _unique_names(names, source)
    limits = _limits(raw_limits, names, limits_at, source)
    home = _matrix4(obj["home"], f"{source}: 'home'")
    if key == "body_screws":
        # Check M first (a chain of no joints checks only M), then S_i = Ad(M) B_i.
        _build(source, lambda: Chain((), (), np.zeros((0, 6)), home))
        screws = np.asarray(screws @ lie.adjoint(home).T, dtype=np.float64)
    frame = _string(obj.get("frame", "ee"), f"{source}: 'frame'")
    robot = _string(obj.get("robot", ""), f"{source}: 'robot'")
    joint_types = cast("tuple[JointType, ...]", tuple(types))  # Chain checks them
    if "registration" in obj:
        _registration(obj["registration"], source)
    return _build(
        source,
        lambda: Chain(
            tuple(names), joint_types, screws, home, limits=limits, frame=frame, robot=robot
        ),
    )


@dataclasses.dataclass(frozen=True)
class Registration:
    """Where a parameter file's base frame is in the frame that measured it: what ``poekin
    calibrate`` writes beside the robot in its own base frame (the file's ``registration``).

    Attributes:
        T_meas_base: ``(4, 4)`` the base frame's pose in the measuring frame (a tracker's):
            ``T_meas_frame(q) = T_meas_base @ chain.fk(q)``.
        std_m, std_rad: ``(3,)`` standard errors of its position (m) and of small turns (rad)
            about the measuring frame's axes; None where the calibration gave none.
    """

    T_meas_base: FloatArray
    std_m: FloatArray | None
    std_rad: FloatArray | None


def _registration(x: object, source: str) -> Registration:
    at = f"{source}: registration"
    reg = _mapping(x, at, "T_meas_base (4x4), std_m and std_rad")
    if "T_meas_base" not in reg:
        raise InputError(
            f"{at} has no 'T_meas_base', the base frame's 4x4 pose in the measuring frame"
        )
    T = _matrix4(reg["T_meas_base"], f"{at}.T_meas_base")
    _build(source, lambda: check_pose(T, "registration.T_meas_base"))
    std: list[FloatArray | None] = []
    for key in ("std_m", "std_rad"):
        value = reg.get(key)
        if value is None:
            std.append(None)
            continue
        v = np.array(_vector(value, f"{at}.{key}", 3, "one per axis of the measuring frame"))
        if np.any(v < 0):
            raise InputError(f"{at}.{key} holds a negative standard error")
        std.append(v)
    return Registration(T, std[0], std[1])


def _ur_calibration(obj: Mapping[str, Any], source: str, order: URYamlOrder) -> Chain:
    """The chain a ``kinematics:`` document (UR's calibration, ur_calibration's file) gives."""
    segments = ", ".join(UR_SEGMENTS)
    what = f"the segments {segments} (each with {' '.join(UR_ORIGIN_KEYS)}) and a hash"
    kin = _mapping(obj["kinematics"], f"{source}: 'kinematics'", what)
    for key in kin:
        if key not in (*UR_SEGMENTS, "hash"):
            raise InputError(
                f"{source}: 'kinematics' has an unknown segment {key!r}: "
                f"{did_you_mean(str(key), UR_SEGMENTS)}; a UR arm has exactly these six"
            )
    origins = []
    for name in UR_SEGMENTS:
        if name not in kin:
            raise InputError(
                f"{source}: 'kinematics' has no {name!r} segment; a UR calibration has {segments}"
            )
        at = f"{source}: kinematics.{name}"
        segment = _mapping(kin[name], at, " ".join(UR_ORIGIN_KEYS))
        for key in segment:
            if key not in UR_ORIGIN_KEYS:
                raise InputError(
                    f"{at} has an unknown key {key!r}: {did_you_mean(str(key), UR_ORIGIN_KEYS)}"
                )
        for key in UR_ORIGIN_KEYS:
            if key not in segment:
                raise InputError(
                    f"{at} has no {key!r}; each segment gives x y z (m) and roll pitch yaw (rad)"
                )
        origins.append([_number(segment[key], f"{at}.{key}") for key in UR_ORIGIN_KEYS])
    calibration = _string(kin["hash"], f"{source}: kinematics.hash") if "hash" in kin else ""
    _ur_millimetres(origins, source)
    model = nominal_model(origins) or "UR arm"
    robot = f"{model}, UR calibration {calibration}" if calibration else model
    return ur_chain(origins, robot=robot, order=order)


# A UR segment's lengths: the longest of any model is the UR20's forearm, 0.862 m.
_UR_LONGEST_M = 2.0


def _ur_millimetres(origins: Sequence[Sequence[float]], source: str) -> None:
    """Refuse a UR file whose lengths no UR arm has (the file in millimetres, most likely)."""
    lengths = np.abs(np.asarray(origins)[:, :3])
    if lengths.max() <= _UR_LONGEST_M:
        return
    i, k = np.unravel_index(int(np.argmax(lengths)), lengths.shape)
    value = float(np.asarray(origins)[i][k])
    model = nominal_model(np.hstack([np.asarray(origins)[:, :3] / 1e3, np.asarray(origins)[:, 3:]]))
    match = f" (divided by 1000 they are a {model}'s)" if model else ""
    raise InputError(
        f"{source}: kinematics.{UR_SEGMENTS[i]}.{UR_ORIGIN_KEYS[k]} is {value:g}, longer than "
        f"any UR arm's segment (the longest, a UR20's forearm, is 0.862 m): the file's lengths "
        f"look like millimetres{match}; write x, y, z in metres"
    )


def _check_reach(chain: Chain, source: str) -> None:
    """Refuse a chain whose end frame is farther from one of its revolute axes than any arm
    reaches (:data:`MAX_REACH_M`)."""
    revolute = [i for i, t in enumerate(chain.joint_types) if t == "revolute"]
    if not revolute:
        return
    S = chain.screws[revolute]
    w = S[:, :3] / np.linalg.norm(S[:, :3], axis=1)[:, None]
    points = np.cross(w, S[:, 3:])
    reach = np.linalg.norm(np.cross(chain.home[:3, 3] - points, w), axis=1)
    k = int(np.argmax(reach))
    if reach[k] <= MAX_REACH_M:
        return
    name = chain.joint_names[revolute[k]]
    raise InputError(
        f"{source}: the end frame is {reach[k]:.4g} m from joint {name!r}'s axis, farther than "
        f"any arm reaches ({MAX_REACH_M:g} m; the longest, the ISS's Canadarm2, reaches 17.6 m): "
        f"the file's lengths look like millimetres; write them in metres"
    )


def params_from_dict(
    obj: object, source: str, *, ur_yaml_order: URYamlOrder = "description"
) -> Chain | DHTable:
    """A DH table or a PoE chain from parsed JSON/YAML (dicts, lists, numbers). No I/O.

    Args:
        obj: the parsed document; see the module docstring for the accepted shapes.
        source: where ``obj`` came from (a file name), put at the start of every error message.
        ur_yaml_order: how a UR calibration's angles compose
            (:data:`~poekin.io.ur_kinematics.UR_YAML_ORDERS`): ``"description"`` as ur_description
            reads them (the default), ``"controller"`` as ur_calibration wrote them.

    Returns:
        A :class:`~poekin.dh.DHTable` (the document has ``rows``) or a :class:`Chain` (it has
        ``screws``, ``body_screws`` or ``joints``, and ``home``; or ``kinematics``, a UR
        calibration: the chain from UR's ``base`` to ``tool0``, see
        :mod:`poekin.io.ur_kinematics`). ``describe()`` of either reads back to the same kinematics.

    Raises:
        InputError: the document is malformed, a joint's lower limit is above its upper, or its
            lengths are beyond any arm's (millimetres?); the message names the source and the
            place.
    """
    check_order(ur_yaml_order)
    result = _params(obj, source, ur_yaml_order)
    _check_reach(result.to_chain() if isinstance(result, DHTable) else result, source)
    return result


def _params(obj: object, source: str, ur_yaml_order: URYamlOrder) -> Chain | DHTable:
    if not isinstance(obj, Mapping):
        raise InputError(f"{source}: the top level is {_kind(obj)}, expected an object: {_NEITHER}")
    is_dh = "rows" in obj
    is_poe = any(k in obj for k in ("screws", "body_screws", "joints"))
    if is_dh and is_poe:
        raise InputError(
            f"{source}: has both 'rows' (a DH table) and PoE screws; keep one of the two"
        )
    if "kinematics" in obj:
        if is_dh or is_poe:
            raise InputError(
                f"{source}: has both 'kinematics' (a UR calibration) and "
                f"{'rows' if is_dh else 'PoE screws'}; keep one of the two"
            )
        return _ur_calibration(obj, source, ur_yaml_order)
    if is_dh:
        return _dh_table(obj, source)
    if is_poe:
        return _poe_chain(obj, source)
    raise InputError(f"{source}: {_NEITHER}")


# --- files ------------------------------------------------------------------------------------


class _DuplicateKeyError(Exception):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _reject_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``json.loads`` hook: a key twice in one object is an error (JSON keeps the last)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKeyError(key)
        out[key] = value
    return out


def _parse_json(text: str, source: str) -> object:
    import json

    try:
        return json.loads(text, object_pairs_hook=_reject_duplicate_keys)
    except json.JSONDecodeError as e:
        raise InputError(
            f"{source}: not valid JSON: {e.msg} at line {e.lineno}, column {e.colno}"
        ) from e
    except _DuplicateKeyError as e:
        raise InputError(
            f"{source}: the key {e.key!r} appears twice in one object; keep one"
        ) from e


def _parse_yaml(text: str, source: str) -> object:
    from poekin._extras import require

    yaml = require(
        "yaml", "yaml", f"reading {source}", package="PyYAML", instead="or save it as JSON"
    )
    try:
        result: object = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or type(e).__name__
        raise InputError(f"{source}: not valid YAML: {problem}{where}") from e
    return result


def _read_text(path: Path, source: str) -> str:
    try:
        data = path.read_bytes()
    except OSError as e:
        raise InputError(
            f"cannot read {source}: {e.strerror or e}; check that the file is readable"
        ) from e
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputError(
            f"{source}: not UTF-8 text (byte {e.start}); save it as UTF-8 JSON or YAML"
        ) from e
    if not text.strip():
        raise InputError(f"{source} is empty; write a DH table ('rows') or a PoE set ('screws')")
    return text


def load_params(
    spec: str | os.PathLike[str], *, ur_yaml_order: URYamlOrder = "description"
) -> Chain | DHTable:
    """A named parameter set, or a DH table / PoE set read from a ``.json``/``.yaml`` file.

    Args:
        spec: a key of :data:`~poekin.io.params.PARAM_SETS` (e.g. ``"ur5e-dh"``), or the path of
            a ``.json``, ``.yaml`` or ``.yml`` file in a shape :func:`params_from_dict` accepts,
            UR's calibration file (``kinematics:``, from ``ur_calibration``) included. YAML needs
            PyYAML (the extra ``poekin[yaml]``).
        ur_yaml_order: how a UR calibration file's angles compose: ``"description"`` (the
            default) as ur_description reads them, ``"controller"`` as ur_calibration wrote
            them (see :mod:`poekin.io.ur_kinematics`).

    Returns:
        A :class:`Chain` or a :class:`~poekin.dh.DHTable`.

    Raises:
        UnknownParamsError: ``spec`` looks like a name (no folder, no suffix) but is not one.
        InputError: no such file, a folder, a suffix other than .json/.yaml/.yml, an empty or
            unreadable file, a syntax error, or a malformed document.
    """
    check_order(ur_yaml_order)
    text = os.fspath(spec)
    if text in PARAM_SETS:
        return named_params(text)
    return params_from_dict(_document(text), text, ur_yaml_order=ur_yaml_order)


def load_registration(spec: str | os.PathLike[str]) -> Registration:
    """The ``registration`` of a parameter file that ``poekin calibrate`` wrote: where the
    robot's base frame is in the measuring frame (the tracker's).

    >>> chain = poekin.load_params("my_robot.json")             # the robot in its base frame
    >>> reg = poekin.load_registration("my_robot.json")
    >>> T_meas_frame = reg.T_meas_base @ chain.fk(q)            # as the tracker sees it

    Raises:
        InputError: the file cannot be read, or has no ``registration`` (only calibrations
            carry one), or a malformed one.
    """
    text = os.fspath(spec)
    obj = None if text in PARAM_SETS else _document(text)
    if not isinstance(obj, Mapping) or "registration" not in obj:
        raise InputError(
            f"{text} has no 'registration' (the base frame in the measuring frame): only the "
            "parameter files that poekin calibrate writes carry one"
        )
    return _registration(obj["registration"], text)


def _document(text: str) -> object:
    """The parsed document of the parameter file ``text`` (not a named set)."""
    path = Path(text)
    suffixes = ".json or .yaml (.yml)"
    if path.is_dir():
        raise InputError(
            f"{text} is a directory; give a parameter file ({suffixes}) or a named set: "
            f"{did_you_mean(path.name, PARAM_SETS)}"
        )
    suffix = path.suffix.lower()
    if not path.exists():
        separators = {"/", os.sep, os.altsep or "/"}
        if not path.suffix and not any(s in text for s in separators):
            raise UnknownParamsError(
                f"unknown parameter set {text!r}: {did_you_mean(text, PARAM_SETS)}; "
                f"or give a parameter file ({suffixes})"
            )
        raise InputError(
            f"no such file {text!r}; give an existing parameter file ({suffixes}) or a named "
            f"set: {did_you_mean(path.stem, PARAM_SETS)}"
        )
    if suffix not in FILE_SUFFIXES:
        raise InputError(
            f"{text}: a parameter file must end in {suffixes}, got {path.suffix or 'no suffix'!r}; "
            "rename it, or give a named set"
        )
    content = _read_text(path, text)
    obj = _parse_json(content, text) if suffix == ".json" else _parse_yaml(content, text)
    if obj is None:
        raise InputError(f"{text} is empty; write a DH table ('rows') or a PoE set ('screws')")
    return obj
