"""Plan the poses to measure: configurations that make the parameters identifiable.

Greedy D-optimal design: from random candidate configurations within the joint limits, add one
at a time the candidate that most increases ``log det(J^T J)`` of the identification Jacobian
(:func:`~.identify.scaled_jacobian`, at the model), the product of its singular values that the
observability index O1 measures. A candidate's gain is ``log det(I + J_c A^-1 J_c^T)`` (the
matrix determinant lemma, with ``A`` the information so far), so each step costs one solve.
The result is deterministic for a seed.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from poekin.calibration._blas import one_thread
from poekin.calibration.identify import observability, scaled_jacobian
from poekin.calibration.model import (
    CalibrationModel,
    Measure,
    State,
    as_chain,
    generic_point,
    model_of,
)
from poekin.chain import Chain
from poekin.errors import InputError
from poekin.verification.verify import sample_joint_values, whole_number

if TYPE_CHECKING:
    from poekin.io.sources import LoadedModel

__all__ = ["design_state", "plan_poses", "quality"]

FloatArray = NDArray[np.float64]
_PRIOR_M, _PRIOR_RAD = 1e-3, 1e-2  # the units of the corrections (as calibrate's defaults)
_CANDIDATES_PER_POSE = 40
_MIN_CANDIDATES = 2000
_MAX_CANDIDATES = 8000  # the default's bound: each pose picked costs a pass over the candidates
#: The most poses a plan holds: a tracker session measures tens to hundreds; a plan this long
#: takes some 30 s (greedy: one pass over the candidates per pose; UR5e, 2 cores)
MAX_POSES = 1000
_RIDGE = 1e-9  # the information starts at this times a typical pose's (so that A inverts)


def sampling_chain(chain: Chain) -> Chain:
    """``chain`` with revolute limits wider than a turn clipped to ``[-pi, pi]`` (every
    orientation of a joint is in one turn), for sampling configurations."""
    revolute = np.array([t == "revolute" for t in chain.joint_types])
    assert chain.limits is not None
    limits = np.where(revolute[:, None], np.clip(chain.limits, -np.pi, np.pi), chain.limits)
    return dataclasses.replace(chain, limits=limits)


def design_state(model: CalibrationModel) -> State:
    """The model as planned for: nominal, the measured point off every axis for positions-only
    data (as the structure is analysed: :func:`~.model.generic_point`)."""
    state = model.nominal()
    if model.measure == "position":
        x = state.x.copy()
        x[list(model.tool_shift_index)] = generic_point(model.chain)
        state = State(state.base, x)
    return state


def quality(model: CalibrationModel, q: FloatArray) -> tuple[float, float]:
    """O1 and the condition number of the poses ``q`` at the model (:func:`design_state`)."""
    obs = observability(model, design_state(model), q, _PRIOR_M, _PRIOR_RAD)
    return obs.o1, obs.condition_number


def plan_poses(
    model: Chain | str | os.PathLike[str] | LoadedModel,
    n: int,
    *,
    frame: str | None = None,
    measure: Measure = "pose",
    candidates: int | None = None,
    seed: int = 0,
    progress: Callable[[int], None] | None = None,
) -> FloatArray:
    """``(n, dof)`` configurations within the joint limits to measure for a calibration.

    Args:
        model: the chain, or what :func:`poekin.load` takes, with ``frame``.
        n: how many poses (at least as many as the parameters need).
        measure: ``"pose"`` (the tracker measures position and orientation) or
            ``"position"`` (a point only).
        candidates: random configurations to choose from (default 40 per pose, from 2,000 to
            8,000, and at least ``n``).
        seed: the candidates' random draw.
        progress: called with the number of poses picked so far, after each (a progress bar).

    Raises:
        InputError: ``n`` too small to identify the parameters or above :data:`MAX_POSES`, or
            ``candidates`` below ``n``.
    """
    from poekin.calibration.identify import minimum_poses, recommended_poses

    with one_thread():  # small matrices: see poekin.calibration._blas
        chain = as_chain(model, frame)
        if measure not in ("pose", "position"):
            raise InputError(f"measure must be 'pose' or 'position', got {measure!r}")
        cm = model_of(chain, measure)
        n = whole_number(n, "the number of poses", 1)
        need = minimum_poses(cm)
        if n < need:
            raise InputError(
                f"{n} poses give {n * cm.rows_per_pose} measured numbers for {len(cm.free)} "
                f"parameters: plan at least {need}"
            )
        if n > MAX_POSES:
            raise InputError(
                f"{n} poses: plan at most {MAX_POSES} (a tracker session measures tens to "
                f"hundreds; from {2 * recommended_poses(cm)} on, more poses only average the noise "
                "down)"
            )
        default = min(max(_MIN_CANDIDATES, _CANDIDATES_PER_POSE * n), max(_MAX_CANDIDATES, n))
        count = default if candidates is None else candidates
        count = whole_number(count, "candidates", n)
        pool = sample_joint_values(sampling_chain(chain), count, seed=seed, within_limits=True)
        m = cm.rows_per_pose
        J = scaled_jacobian(cm, design_state(cm), pool, _PRIOR_M, _PRIOR_RAD)  # (C m, F)
        blocks = J.reshape(count, m, -1)
        F = J.shape[1]
        A_inv = np.eye(F) / (_RIDGE * float(np.mean(np.sum(J * J, axis=0))) * m)
        Y = J @ A_inv  # (C m, F): every candidate's J_c A^-1, kept up to date
        left = np.ones(count, dtype=bool)
        picked: list[int] = []
        for _ in range(n):
            G = np.einsum("cmf,ckf->cmk", blocks, Y.reshape(count, m, F))  # J_c A^-1 J_c^T
            _, gain = np.linalg.slogdet(np.eye(m) + G)
            gain[~left] = -np.inf
            best = int(np.argmax(gain))
            picked.append(best)
            left[best] = False
            # Woodbury: (A + J_b^T J_b)^-1 = A^-1 - K^T (I + J_b K^T)^-1 K, K = J_b A^-1
            K = Y[best * m : (best + 1) * m]
            update = np.linalg.solve(np.eye(m) + blocks[best] @ K.T, K)
            Y = Y - (J @ K.T) @ update
            if progress is not None:
                progress(len(picked))
        return np.asarray(pool[picked], dtype=np.float64)
