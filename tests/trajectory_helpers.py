"""Trajectories the motion-edge tests share, computed here with NumPy alone: a quintic time
scaling between two UR5e configurations, with its exact derivatives."""

from __future__ import annotations

import numpy as np

#: Two UR5e configurations (rad): the elbow up, then turned and bent.
Q_START = np.array([0.0, -1.57, 1.57, 0.0, 0.0, 0.0])
Q_END = np.array([1.2, -0.8, 1.0, -1.2, 0.8, 0.5])


def quintic(
    samples: int = 201, duration: float = 2.0, q0: np.ndarray = Q_START, q1: np.ndarray = Q_END
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``t (K,)``, ``q``, ``qd``, ``qdd`` ``(K, n)``: ``q0 + s(t) (q1 - q0)`` with the quintic
    ``s = 10 tau^3 - 15 tau^4 + 6 tau^5``, ``tau = t / duration`` (Modern Robotics, eq. 9.9)."""
    t = np.linspace(0.0, duration, samples)
    tau = t / duration
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    sd = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
    sdd = (60 * tau - 180 * tau**2 + 120 * tau**3) / duration**2
    dq = q1 - q0
    return t, q0 + np.outer(s, dq), np.outer(sd, dq), np.outer(sdd, dq)
