"""Verification of PoE forward kinematics against MuJoCo's ``mj_forward``.

Errors between a reference pose ``T_ref`` (MuJoCo) and a pose ``T`` (PoE):

* position error: ``|p_ref - p|`` in metres;
* orientation error: the geodesic angle of ``R_ref R^T`` in radians, from ``atan2`` (no
  ``arccos``, so it stays accurate near 0 where float-precision agreement lives).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from poekin import lie
from poekin.chain import Chain
from poekin.dh import DHTable
from poekin.errors import InputError
from poekin.import_mujoco import chain_from_model, find_frame, frame_pose
from poekin.sources import LoadedModel

__all__ = [
    "DEFAULT_ORI_TOL",
    "DEFAULT_POS_TOL",
    "VerifyReport",
    "mujoco_poses",
    "pose_errors",
    "sample_joint_values",
    "verify",
]

FloatArray = NDArray[np.float64]
DEFAULT_POS_TOL = 1e-5  # m: the lab's bar, far above float precision (~1e-15 m)
DEFAULT_ORI_TOL = 1e-4  # rad: likewise
# Range sampled for a prismatic joint that has no limits (a revolute one samples [-2 pi, 2 pi]).
UNLIMITED_SLIDE_RANGE = (-1.0, 1.0)


def sample_joint_values(
    chain: Chain, n: int, *, seed: int = 0, within_limits: bool = False
) -> FloatArray:
    """``(n, dof)`` joint values, uniform per joint.

    Revolute joints sample ``[-2 pi, 2 pi]`` rad, or their limits with ``within_limits``.
    Prismatic joints sample their limits, or ``[-1, 1]`` m if they have none.
    """
    assert chain.limits is not None
    revolute = np.array([t == "revolute" for t in chain.joint_types], dtype=bool)
    lo = np.where(revolute, -2 * np.pi, chain.limits[:, 0])
    hi = np.where(revolute, 2 * np.pi, chain.limits[:, 1])
    if within_limits:
        lo = np.where(np.isfinite(chain.limits[:, 0]), chain.limits[:, 0], lo)
        hi = np.where(np.isfinite(chain.limits[:, 1]), chain.limits[:, 1], hi)
    lo = np.where(np.isfinite(lo), lo, UNLIMITED_SLIDE_RANGE[0])
    hi = np.where(np.isfinite(hi), hi, UNLIMITED_SLIDE_RANGE[1])
    rng = np.random.default_rng(seed)
    return rng.uniform(lo, hi, size=(n, chain.n_joints))


def pose_errors(T_ref: FloatArray, T: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Position (m) and orientation (rad) errors between ``(..., 4, 4)`` poses."""
    pos = np.linalg.norm(T_ref[..., :3, 3] - T[..., :3, 3], axis=-1)
    ori = lie.rotation_angle(T_ref[..., :3, :3] @ np.swapaxes(T[..., :3, :3], -1, -2))
    return pos, np.asarray(ori, dtype=np.float64)


def mujoco_poses(
    model: mujoco.MjModel, chain: Chain, q: FloatArray, *, progress: bool = False
) -> FloatArray:
    """``(N, 4, 4)`` poses of ``chain.frame`` from ``mj_forward`` for ``q`` of shape ``(N, n)``.

    Joints not in the chain stay at ``qpos0``. ``chain`` must come from ``model``.
    """
    if chain.qpos_indices is None:
        raise ValueError("the chain was not imported from a MuJoCo model")
    kind, fid, _ = find_frame(model, chain.frame)
    idx = list(chain.qpos_indices)
    data = mujoco.MjData(model)
    out = np.zeros((len(q), 4, 4))
    out[:, 3, 3] = 1.0
    rows = tqdm(
        range(len(q)),
        desc="mj_forward",
        unit="q",
        disable=None if progress else True,
        delay=0.5,
        leave=False,
    )
    for k in rows:
        data.qpos[:] = model.qpos0
        data.qpos[idx] = q[k]
        mujoco.mj_forward(model, data)
        frame_pose(data, kind, fid, out=out[k])
    return out


@dataclasses.dataclass(frozen=True)
class VerifyReport:
    """The outcome of :func:`verify`.

    ``pos_err`` / ``ori_err`` map a method (``"space PoE"``, ``"body PoE"``, ``"DH table"``) to
    ``(N,)`` errors
    in m / rad. The ``max_*`` and ``median_*`` figures are the worst over the methods.
    """

    robot: str
    frame: str
    samples: int
    seed: int
    within_limits: bool
    pos_tol: float
    ori_tol: float
    pos_err: Mapping[str, FloatArray]
    ori_err: Mapping[str, FloatArray]

    def _worst(self, stat: str) -> float:
        return max((m[stat] for m in self.per_method().values()), default=0.0)

    @property
    def max_pos_err_m(self) -> float:
        return self._worst("max_pos_err_m")

    @property
    def median_pos_err_m(self) -> float:
        return self._worst("median_pos_err_m")

    @property
    def max_ori_err_rad(self) -> float:
        return self._worst("max_ori_err_rad")

    @property
    def median_ori_err_rad(self) -> float:
        return self._worst("median_ori_err_rad")

    @property
    def passed(self) -> bool:
        return self.max_pos_err_m <= self.pos_tol and self.max_ori_err_rad <= self.ori_tol

    def summary(self) -> dict[str, Any]:
        """The JSON object printed by ``poekin verify --json``."""
        return {
            "robot": self.robot,
            "frame": self.frame,
            "samples": self.samples,
            "seed": self.seed,
            "max_pos_err_m": self.max_pos_err_m,
            "median_pos_err_m": self.median_pos_err_m,
            "max_ori_err_rad": self.max_ori_err_rad,
            "median_ori_err_rad": self.median_ori_err_rad,
            "passed": self.passed,
        }

    def per_method(self) -> dict[str, dict[str, float]]:
        """``{method: {max_pos_err_m, median_pos_err_m, max_ori_err_rad, median_ori_err_rad}}``."""
        return {
            m: {
                "max_pos_err_m": float(np.max(self.pos_err[m], initial=0.0)),
                "median_pos_err_m": float(np.median(self.pos_err[m])) if self.samples else 0.0,
                "max_ori_err_rad": float(np.max(self.ori_err[m], initial=0.0)),
                "median_ori_err_rad": float(np.median(self.ori_err[m])) if self.samples else 0.0,
            }
            for m in self.pos_err
        }


def verify(
    loaded: LoadedModel,
    frame: str | None = None,
    *,
    chain: Chain | None = None,
    params: Chain | DHTable | None = None,
    samples: int = 1000,
    seed: int = 0,
    within_limits: bool = False,
    pos_tol: float = DEFAULT_POS_TOL,
    ori_tol: float = DEFAULT_ORI_TOL,
    progress: bool = False,
) -> VerifyReport:
    """Compare space- and body-form PoE with ``mj_forward`` on random joint values.

    Args:
        loaded: the model (see :func:`poekin.sources.load_model`).
        frame: site or body name; None means the model's only site.
        chain: the model's chain, which says which joints move; by default the one derived
            from ``loaded``. A chain given here must carry ``qpos_indices``.
        params: the parameters to check, in the model's joint order: a PoE chain (its space and
            body forms are checked) or a DH table (the table's own FK and the space and body
            forms of its PoE conversion). By default ``chain`` itself.
        samples, seed: how many configurations, from which random seed.
        within_limits: sample within the joint limits instead of ``[-2 pi, 2 pi]``.
        pos_tol, ori_tol: pass/fail thresholds for the maxima (m, rad).
        progress: show a progress bar on a terminal.
    """
    chain = chain or chain_from_model(loaded.model, frame, robot=loaded.robot)
    checked = chain if params is None else params
    if checked.n_joints != chain.n_joints:
        raise InputError(
            f"the parameters have {checked.n_joints} joints but {loaded.robot}'s chain to "
            f"{chain.frame!r} has {chain.n_joints} ({', '.join(chain.joint_names)})"
        )
    q = sample_joint_values(chain, samples, seed=seed, within_limits=within_limits)
    T_ref = mujoco_poses(loaded.model, chain, q, progress=progress)
    errors = {}
    if isinstance(checked, DHTable):
        errors["DH table"] = pose_errors(T_ref, checked.fk(q))
        checked = checked.to_chain()
    errors["space PoE"] = pose_errors(T_ref, checked.fk(q))
    errors["body PoE"] = pose_errors(T_ref, checked.fk_body(q))
    return VerifyReport(
        robot=loaded.robot,
        frame=chain.frame,
        samples=samples,
        seed=seed,
        within_limits=within_limits,
        pos_tol=pos_tol,
        ori_tol=ori_tol,
        pos_err={m: e[0] for m, e in errors.items()},
        ori_err={m: e[1] for m, e in errors.items()},
    )
