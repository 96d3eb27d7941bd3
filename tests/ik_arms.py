"""Arms for the IK tests, each with MuJoCo's compile of it so that every answer is checked by
``mj_kinematics``: Menagerie models, arms written as MJCF from published dimensions, and a PoE
chain (e.g. from a DH table) written as MJCF (nested bodies at the origin, one hinge per screw
axis: MuJoCo then computes the same product of exponentials with its own code)."""

from __future__ import annotations

import dataclasses
import pathlib

import mujoco
import numpy as np
from helpers import load_quiet, mj_frame_pose

import poekin

FloatArray = np.ndarray


@dataclasses.dataclass(frozen=True)
class Arm:
    name: str
    loaded: poekin.LoadedModel
    chain: poekin.Chain

    def mujoco_poses(self, q: FloatArray) -> FloatArray:
        """``(m, 4, 4)`` poses of the chain's end frame from MuJoCo for ``(m, 6)`` ``q``."""
        m = self.loaded.model
        d = mujoco.MjData(m)
        idx = list(self.chain.qpos_indices or range(self.chain.n_joints))
        site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, self.chain.frame)
        kind, fid = ("site", site) if site >= 0 else ("body", m.body(self.chain.frame).id)
        out = np.empty((len(q), 4, 4))
        for k, row in enumerate(np.asarray(q).reshape(-1, 6)):
            d.qpos[idx] = row
            mujoco.mj_kinematics(m, d)
            out[k] = mj_frame_pose(m, d, kind, fid)
        return out

    def sample(self, n: int, seed: int) -> FloatArray:
        """``(n, 6)`` joint values uniform within the limits (unlimited joints: [-pi, pi])."""
        lo = np.maximum(self.chain.limits[:, 0], -np.pi)
        hi = np.minimum(self.chain.limits[:, 1], np.pi)
        return np.random.default_rng(seed).uniform(lo, hi, (n, 6))


def menagerie(name: str, robot: str) -> Arm:
    loaded = load_quiet(robot)
    return Arm(name, loaded, poekin.load(loaded))


def from_mjcf(name: str, xml: str, folder: pathlib.Path, frame: str = "flange") -> Arm:
    path = folder / f"{name}.xml"
    path.write_text(xml)
    loaded = poekin.load_model(path)
    return Arm(name, loaded, poekin.load(loaded, frame))


def mjcf_of_chain(chain: poekin.Chain) -> str:
    """MJCF whose bodies all sit at the world origin, unturned, with one hinge per screw axis
    (its point and direction at ``q = 0``) and a site ``flange`` at the home pose."""
    body = ""
    for name, s in zip(reversed(chain.joint_names), reversed(chain.screws), strict=True):
        w, point = s[:3], np.cross(s[:3], s[3:])
        joint = f'<joint name="{name}" pos="{_num(point)}" axis="{_num(w)}"/>'
        inner = body or (
            f'<site name="flange" pos="{_num(chain.home[:3, 3])}" '
            f'quat="{_num(poekin.rotation_to_quat(chain.home[:3, :3]))}"/>'
        )
        body = f'<body name="b_{name}">{joint}<geom size="0.01"/>{inner}</body>'
    return f'<mujoco><compiler angle="radian"/><worldbody>{body}</worldbody></mujoco>'


def from_chain(name: str, chain: poekin.Chain, folder: pathlib.Path) -> Arm:
    """The chain, and MuJoCo's compile of :func:`mjcf_of_chain` to check it against."""
    path = folder / f"{name}.xml"
    path.write_text(mjcf_of_chain(chain))
    loaded = poekin.load_model(path)
    assert np.allclose(poekin.load(loaded, "flange").screws, chain.screws, atol=1e-15)
    return Arm(name, loaded, chain)


def _num(v: FloatArray) -> str:
    return " ".join(repr(float(x)) for x in v)


def _body(name: str, pos: str, axis: str, lim: tuple[float, float], inner: str) -> str:
    return (
        f'<body name="{name}" pos="{pos}"><geom size="0.02"/>'
        f'<joint name="j_{name}" axis="{axis}" range="{lim[0]} {lim[1]}"/>{inner}</body>'
    )


def _arm_xml(model: str, links: list[tuple[str, str, tuple[float, float]]], flange: str) -> str:
    """An MJCF serial arm: each link a body at ``pos`` in its parent with a hinge ``axis``
    (radians ``range``), and a site ``flange`` in the last."""
    inner = f'<site name="flange" pos="{flange}"/>'
    for k in reversed(range(len(links))):
        pos, axis, lim = links[k]
        inner = _body(f"link{k + 1}", pos, axis, lim, inner)
    return (
        f'<mujoco model="{model}"><compiler angle="radian"/><worldbody>{inner}</worldbody></mujoco>'
    )


#: PUMA 560 (P. I. Corke, "A Robotics Toolbox for MATLAB", 1996: a2 = 0.4318, a3 = 0.0203,
#: d3 = 0.15005, d4 = 0.4318 m; shoulder 0.6604 m up; flange 0.05635 m past the wrist centre),
#: the upper arm along x and the forearm up at q = 0; Corke's joint ranges.
PUMA560_XML = _arm_xml(
    "puma560",
    [
        ("0 0 0.6604", "0 0 1", (-2.7925, 2.7925)),
        ("0 0 0", "0 1 0", (-3.9270, 0.7854)),
        ("0.4318 0.15005 0", "0 1 0", (-0.7854, 3.9270)),
        ("0.0203 0 0.4318", "0 0 1", (-1.9199, 2.9671)),
        ("0 0 0", "0 1 0", (-1.7453, 1.7453)),
        ("0 0 0", "0 0 1", (-4.6426, 4.6426)),
    ],
    "0 0 0.05635",
)

#: ABB IRB 120 (product specification: axis 2 at 0.290 m, upper arm 0.270 m, forearm offset
#: 0.070 m, forearm 0.302 m, flange 0.072 m past the wrist centre; joint ranges +-165, +-110,
#: -110/+70, +-160, +-120, +-400 deg), upper arm up and forearm along x at q = 0.
IRB120_XML = _arm_xml(
    "irb120",
    [
        ("0 0 0", "0 0 1", (-2.8798, 2.8798)),
        ("0 0 0.29", "0 1 0", (-1.9199, 1.9199)),
        ("0 0 0.27", "0 1 0", (-1.9199, 1.2217)),
        ("0 0 0.07", "1 0 0", (-2.7925, 2.7925)),
        ("0.302 0 0", "0 1 0", (-2.0944, 2.0944)),
        ("0 0 0", "1 0 0", (-6.9813, 6.9813)),
    ],
    "0.072 0 0",
)

#: A made-up arm whose axes 2 and 3 meet (joint 3 rolls the upper arm about its own length)
#: while axis 1 misses axis 2 by 0.1 m and is not parallel to it: only the "axes 2 and 3 meet"
#: split applies. Spherical wrist 0.35 m along the upper arm, 0.1 m up.
ROLL_SHOULDER_XML = _arm_xml(
    "roll_shoulder",
    [
        ("0 0 0", "0 0 1", (-3.0, 3.0)),
        ("0.1 0 0.4", "0 1 0", (-2.0, 2.0)),
        ("0 0 0", "1 0 0", (-3.0, 3.0)),
        ("0.35 0 0.1", "1 0 0", (-3.0, 3.0)),
        ("0 0 0", "0 1 0", (-2.0, 2.0)),
        ("0 0 0", "1 0 0", (-3.0, 3.0)),
    ],
    "0.08 0 0",
)
