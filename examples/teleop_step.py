"""Teleoperation at 500 Hz: poekin's differential step inside a MuJoCo simulation's loop.

A target moves on a circle (the UR5e's tool) or two circles (the ALOHA's grippers); at every
tick the differential step turns the targets into joint velocities within the limits
(``chain.ik_step`` for the UR5e, a chain: the compiled kernel's step; ``tree.ik_step`` for the
ALOHA's two arms), the simulation integrates them (``mj_integratePos``, then ``mj_forward``),
and the frames follow.
It prints the median step time and how far each frame trails its target, measured by
MuJoCo::

    python examples/teleop_step.py --seconds 2

The targets are 1 cm circles at 0.5 Hz, each tick's target the one for the end of that tick:
with the step's gain of 1 a frame lands within nanometres of it (the step is first order in
the 0.06 mm its target moves a tick) as long as the velocity limits allow; the arms start
bent, away from the singular straight pose.
"""

from __future__ import annotations

import argparse
import time
import warnings

import mujoco
import numpy as np

import poekin

RATE = 500.0  # Hz
RADIUS = 0.01  # m
FREQUENCY = 0.5  # Hz


def _frame_pose(model: mujoco.MjModel, data: mujoco.MjData, frame: str) -> np.ndarray:
    T = np.eye(4)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame)
    if site >= 0:
        T[:3, :3], T[:3, 3] = data.site_xmat[site].reshape(3, 3), data.site_xpos[site]
    else:
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, frame)
        T[:3, :3], T[:3, 3] = data.xmat[body].reshape(3, 3), data.xpos[body]
    return T


# Starts away from the arms' singular poses (both arms straight at qpos0 = 0 lose a direction):
# the UR5e's elbow and wrist bent, each ALOHA arm's shoulder, elbow and wrist
STARTS = {
    "universal_robots_ur5e": [0.0, -1.2, 1.4, -1.8, -1.57, 0.0],
    "aloha": [0.0, -0.6, 0.6, 0.0, 0.6, 0.0, 0.02, 0.02] * 2,
}


def run(robot: str, frames: tuple[str, ...], seconds: float) -> tuple[float, float]:
    """The median step time (s) and the largest distance a frame trailed its target (m)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        loaded = poekin.load_model(robot)
    tree, model = poekin.load_tree(loaded), loaded.model
    chain = poekin.load(loaded) if len(frames) == 1 else None  # one end frame: a chain
    data = mujoco.MjData(model)
    data.qpos[:] = STARTS[robot]
    mujoco.mj_forward(model, data)
    start = {f: _frame_pose(model, data, f) for f in frames}
    dt = 1.0 / RATE
    times, trail = [], 0.0
    for tick in range(int(seconds * RATE)):
        t = (tick + 1) * dt
        phase = 2 * np.pi * FREQUENCY * t
        targets = {}
        for k, f in enumerate(frames):
            T = start[f].copy()
            sign = 1.0 if k == 0 else -1.0
            T[:3, 3] += RADIUS * np.array([np.cos(phase) - 1.0, sign * np.sin(phase), 0.0])
            targets[f] = T
        began = time.perf_counter()
        if chain is not None:
            qvel = chain.ik_step(targets[frames[0]], data.qpos, dt, velocity_limits=np.pi)
        else:
            qvel = tree.ik_step(targets, data.qpos, dt, velocity_limits=np.pi)
        times.append(time.perf_counter() - began)
        mujoco.mj_integratePos(model, data.qpos, qvel, dt)
        mujoco.mj_forward(model, data)
        for f, T in targets.items():
            trail = max(trail, float(np.linalg.norm(_frame_pose(model, data, f)[:3, 3] - T[:3, 3])))
    return float(np.median(times)), trail


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated time per robot")
    args = parser.parse_args()
    for robot, frames in (
        ("universal_robots_ur5e", ("attachment_site",)),
        ("aloha", ("left/gripper", "right/gripper")),
    ):
        step, trail = run(robot, frames, args.seconds)
        print(
            f"{robot}: {int(args.seconds * RATE)} ticks at {RATE:.0f} Hz, median step "
            f"{step * 1e6:.3g} us, frames within {trail * 1e3:.1e} mm of their targets"
        )


if __name__ == "__main__":
    main()
