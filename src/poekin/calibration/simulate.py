"""A robot that differs from its model, measured from afar: the truth for trying a calibration.

:func:`simulate_robot` edits the model with ``mujoco.MjSpec`` (never with poekin): each body on
the way to the end frame is moved and turned a little, each joint axis tilted and its anchor
moved, the end frame (the tool) moved and turned, and the whole robot placed in a measuring
frame about 2 m away, turned any way. The joints' encoders read ``q`` while the joints stand at
``q + offsets``. Poses come from MuJoCo's ``mj_forward`` on the compiled copy.
"""

from __future__ import annotations

import dataclasses
import os
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.chain import Chain, as_joint_values
from poekin.errors import InputError, ModelError
from poekin.verification.verify import random_generator

if TYPE_CHECKING:
    import mujoco

__all__ = ["SimulatedRobot", "simulate_robot"]

FloatArray = NDArray[np.float64]


@dataclasses.dataclass(frozen=True, eq=False)
class SimulatedRobot:
    """A perturbed robot in its measuring frame (see :func:`simulate_robot`).

    Attributes:
        model: the compiled, perturbed MuJoCo model; its world frame is the measuring frame.
        chain: the nominal chain it was made from (joint names, qpos indices, frame).
        offsets: ``(n,)`` encoder offsets: the joints stand at ``q + offsets`` (rad, or m).
        base: ``(4, 4)`` the nominal model's world frame in the measuring frame.
    """

    model: mujoco.MjModel
    chain: Chain
    offsets: FloatArray
    base: FloatArray
    kind: str
    frame_id: int

    def poses(self, q: ArrayLike) -> FloatArray:
        """``(N, 4, 4)`` poses of the end frame in the measuring frame for encoder readings
        ``q`` ``(N, n)``, by ``mj_forward``."""
        import mujoco

        q = as_joint_values(q, self.chain.n_joints, what="encoder readings")
        q = np.atleast_2d(q)
        assert self.chain.qpos_indices is not None
        data = mujoco.MjData(self.model)
        out = np.zeros((len(q), 4, 4))
        out[:, 3, 3] = 1.0
        qpos0 = self.model.qpos0.copy()
        for k, row in enumerate(q):
            data.qpos[:] = qpos0
            data.qpos[list(self.chain.qpos_indices)] = row + self.offsets
            mujoco.mj_forward(self.model, data)
            if self.kind == "site":
                out[k, :3, :3] = data.site_xmat[self.frame_id].reshape(3, 3)
                out[k, :3, 3] = data.site_xpos[self.frame_id]
            else:
                out[k, :3, :3] = data.xmat[self.frame_id].reshape(3, 3)
                out[k, :3, 3] = data.xpos[self.frame_id]
        return out

    def measure(
        self,
        q: ArrayLike,
        *,
        noise_m: float = 1e-4,
        noise_rad: float = 1e-4,
        positions: bool = False,
        seed: int = 0,
    ) -> FloatArray:
        """Measured poses ``(N, 4, 4)`` (or positions ``(N, 3)``) for encoder readings ``q``:
        :meth:`poses` with Gaussian noise of ``noise_m`` per axis on the position and a turn of
        ``noise_rad`` per axis (in the measuring frame) on the orientation."""
        for name, value in (("noise_m", noise_m), ("noise_rad", noise_rad)):
            if isinstance(value, bool) or not (
                isinstance(value, int | float | np.integer | np.floating)
                and np.isfinite(value)
                and value >= 0
            ):
                raise InputError(
                    f"{name} must be a number >= 0 (a standard deviation), got {value!r}"
                )
        T = self.poses(q)
        rng = random_generator(seed)
        T[:, :3, 3] += rng.normal(scale=noise_m, size=(len(T), 3))
        turn = rng.normal(scale=noise_rad, size=(len(T), 3))
        T[:, :3, :3] = np.asarray(lie.exp_so3(turn)) @ T[:, :3, :3]
        return T[:, :3, 3].copy() if positions else T


def _quat_mul(a: FloatArray, b: FloatArray) -> FloatArray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def _random_turn(rng: np.random.Generator, size: float) -> FloatArray:
    """A rotation vector of length about ``size`` (each axis normal with ``size / sqrt 3``)."""
    return np.asarray(rng.normal(scale=size / np.sqrt(3), size=3), dtype=np.float64)


def _quat_of(turn: FloatArray) -> FloatArray:
    return np.asarray(lie.rotation_to_quat(lie.exp_so3(turn)), dtype=np.float64)


def _quat(R: FloatArray) -> FloatArray:
    return np.asarray(lie.rotation_to_quat(R), dtype=np.float64)


def _moved(
    element: Any, compiled_quat: FloatArray, rng: np.random.Generator, m: float, rad: float
) -> None:
    """Move a body or site by about ``m`` and turn it by about ``rad`` in its parent's frame."""
    import mujoco

    if element.frame is not None:
        raise ModelError(
            f"{element.name!r} sits in a <frame>, which the simulation does not perturb; "
            "flatten the frame into the body"
        )
    quat = np.asarray(element.quat, dtype=np.float64)
    if element.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
        quat = compiled_quat  # euler, axis-angle...: take the compiled orientation
        element.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
    quat = quat / np.linalg.norm(quat)
    element.pos = np.asarray(element.pos) + rng.normal(scale=m / np.sqrt(3), size=3)
    element.quat = _quat_mul(quat, _quat_of(_random_turn(rng, rad)))


def _measuring_frame(rng: np.random.Generator, distance: float) -> FloatArray:
    """A frame ``distance`` from the model's world origin, in a random direction, turned any
    way (a uniformly random rotation)."""
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    direction = rng.normal(size=3)
    T = np.eye(4)
    T[:3, :3] = np.asarray(lie.quat_to_rotation(quat))
    T[:3, 3] = distance * direction / np.linalg.norm(direction)
    return np.asarray(lie.inverse(T), dtype=np.float64)  # the model's world, measured


def simulate_robot(
    source: str | os.PathLike[str] = "universal_robots_ur5e",
    frame: str | None = None,
    *,
    seed: int = 0,
    link_m: float = 1e-3,
    link_rad: float = 2e-3,
    axis_rad: float = 2e-3,
    anchor_m: float = 1e-3,
    tool_m: float = 1e-3,
    tool_rad: float = 2e-3,
    offset_rad: float = 1e-2,
    offset_m: float = 1e-3,
    distance: float = 2.0,
    target: ArrayLike | None = None,
) -> SimulatedRobot:
    """A robot built like ``source`` but not quite, measured from a frame ``distance`` away.

    Args:
        source, frame: the model and its end frame (a site or body), as :func:`poekin.load`.
        seed: the random draw (a whole number).
        link_m, link_rad: each body on the way to ``frame`` moves by about this much and turns
            by about this much in its parent's frame (the size of the random vector).
        axis_rad, anchor_m: each joint's axis tilts by about ``axis_rad`` and its anchor moves
            by about ``anchor_m``.
        tool_m, tool_rad: the end frame (a site; or the body) moves and turns by about this.
        offset_rad, offset_m: the encoder offsets' standard deviation, revolute and prismatic.
        distance: how far the measuring frame is from the model's world origin (m); 0 puts
            them together, unturned.
        target: ``(4, 4)`` a fixed offset of the measured frame from ``frame`` (a target on
            the flange), applied before the tool's perturbation; None for none.

    Returns:
        The simulated robot; its ``measure(q)`` gives what a tracker would measure.
    """

    from poekin.io.import_mujoco import find_frame
    from poekin.io.loading import default_frame, load_tree
    from poekin.io.sources import kinematics_spec, load_model

    loaded = load_model(source)
    tree = load_tree(loaded)
    chain = tree.chain(frame if frame is not None else default_frame(tree))
    kind, frame_id, _ = find_frame(loaded.model, chain.frame)
    rng = random_generator(seed)
    spec = kinematics_spec(source)
    compiled = loaded.model
    element = spec.site(chain.frame) if kind == "site" else spec.body(chain.frame)
    body = element if kind == "body" else element.parent
    path = []
    while body.name != "world":
        path.append(body)
        body = body.parent
    for b in reversed(path):
        _moved(b, compiled.body_quat[b.id], rng, link_m, link_rad)
        for joint in b.joints:
            axis = np.asarray(joint.axis, dtype=np.float64)
            axis = lie.exp_so3(_random_turn(rng, axis_rad)) @ (axis / np.linalg.norm(axis))
            joint.axis = axis
            joint.pos = np.asarray(joint.pos) + rng.normal(scale=anchor_m / np.sqrt(3), size=3)
    if target is not None:
        T = np.asarray(target, dtype=np.float64)
        if T.shape != (4, 4):
            raise InputError(f"target must be a (4, 4) pose, got shape {T.shape}")
        if kind != "site":
            raise InputError("a target offset needs a site as the end frame")
        quat = np.asarray(element.quat, dtype=np.float64)
        R = lie.quat_to_rotation(quat / np.linalg.norm(quat))
        element.pos = np.asarray(element.pos) + R @ T[:3, 3]
        element.quat = _quat_mul(quat / np.linalg.norm(quat), _quat(T[:3, :3]))
    if kind == "site":
        _moved(element, compiled.site_quat[frame_id], rng, tool_m, tool_rad)
    base = _measuring_frame(rng, distance) if distance > 0 else np.eye(4)
    for root in spec.worldbody.bodies:  # place the robot in the measuring frame
        _moved(root, compiled.body_quat[root.id], rng, 0.0, 0.0)  # its orientation as a quat
        quat = np.asarray(root.quat, dtype=np.float64)
        root.pos = base[:3, :3] @ np.asarray(root.pos) + base[:3, 3]
        root.quat = _quat_mul(_quat(base[:3, :3]), quat / np.linalg.norm(quat))
    revolute = np.array([t == "revolute" for t in chain.joint_types])
    offsets = rng.normal(size=chain.n_joints) * np.where(revolute, offset_rad, offset_m)
    model = spec.compile()
    return SimulatedRobot(model, chain, offsets, base, kind, frame_id)
