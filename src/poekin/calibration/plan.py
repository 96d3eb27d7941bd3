"""Plan the poses to measure: configurations that make the parameters identifiable.

Greedy D-optimal design: from random candidate configurations within the joint limits, add one
at a time the candidate that most increases ``log det(J^T J)`` of the identification Jacobian
(:func:`~.identify.scaled_jacobian`, at the model), the product of its singular values that the
observability index O1 measures. A candidate's gain is ``log det(I + J_c A^-1 J_c^T)`` (the
matrix determinant lemma, with ``A`` the information so far), so each step costs one solve.
The result is deterministic for a seed.

Constraints (issue 26: 17 of 40 planned UR5e poses put the flange below its base, into the
table): joint sub-ranges narrow the range the candidates are drawn from; a height and a box for
the end frame's origin, in the chain's base (world) frame, drop the candidates that miss them
before the greedy choice (:class:`PoseConstraints`). Without constraints the plan is what it was.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from poekin._blas import one_thread
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
from poekin.errors import InputError, did_you_mean
from poekin.verification.verify import sample_joint_values, whole_number

if TYPE_CHECKING:
    from poekin.io.sources import LoadedModel

__all__ = [
    "PoseConstraints",
    "PosePlan",
    "design_state",
    "draw_candidates",
    "make_plan",
    "plan_poses",
    "pose_constraints",
    "quality",
]

FloatArray = NDArray[np.float64]
_PRIOR_M, _PRIOR_RAD = 1e-3, 1e-2  # the units of the corrections (as calibrate's defaults)
_CANDIDATES_PER_POSE = 40
_MIN_CANDIDATES = 2000
_MAX_CANDIDATES = 8000  # the default's bound: each pose picked costs a pass over the candidates
#: The most poses a plan holds: a tracker session measures tens to hundreds; a plan this long
#: takes some 30 s (greedy: one pass over the candidates per pose; UR5e, 2 cores)
MAX_POSES = 1000
#: The most candidates a plan picks from: each pose picked costs a pass over them, and each
#: holds its information matrix (some 10 KB for a 6-joint arm: 0.5 GB at this bound)
MAX_CANDIDATES = 50_000
_RIDGE = 1e-9  # the information starts at this times a typical pose's (so that A inverts)
# Constrained candidates: more are drawn while fewer than this many (or than all the candidates
# asked for) meet the constraints, up to _MAX_DRAWN in all (some 0.2 s of FK on a 6R arm)
_ENOUGH_CANDIDATES = _MIN_CANDIDATES
_MAX_DRAWN = 200_000


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


@dataclasses.dataclass(frozen=True)
class PoseConstraints:
    """Where planned poses may go: the joints' ranges, and a region for the end frame's origin.

    Attributes:
        limits: ``(dof, 2)`` the range each joint's candidates are drawn from (rad, m): its
            limits, a revolute joint's within ``[-pi, pi]`` (:func:`sampling_chain`), or the
            sub-range given for it.
        ranged: ``(dof,)`` which joints have a sub-range given.
        above_z: the lowest the end frame's origin may be: its z in the chain's base (world)
            frame (m), or None.
        box: ``(2, 3)`` the lower and upper corners ``(x, y, z)`` of an axis-aligned box, in
            the chain's base frame (m), that the end frame's origin must lie in, or None.
    """

    limits: FloatArray
    ranged: NDArray[np.bool_]
    above_z: float | None = None
    box: FloatArray | None = None

    @property
    def filters(self) -> bool:
        """Whether candidates are dropped (a height or a box is given)."""
        return self.above_z is not None or self.box is not None

    def admits(self, chain: Chain, q: FloatArray) -> NDArray[np.bool_]:
        """``(N,)`` whether each of the ``(N, dof)`` configurations ``q`` puts ``chain``'s end
        frame's origin at ``above_z`` or higher and inside ``box`` (all True without them)."""
        ok = np.ones(len(q), dtype=bool)
        if not self.filters or len(q) == 0:
            return ok
        p = chain.fk(q)[:, :3, 3]
        if self.above_z is not None:
            ok &= p[:, 2] >= self.above_z
        if self.box is not None:
            ok &= np.all((p >= self.box[0]) & (p <= self.box[1]), axis=1)
        return ok

    def region_text(self) -> str:
        """The region in words (m): ``"z >= 0.05 m"``, ``"x in [0.2, 0.6], ... m"``."""
        parts = [] if self.above_z is None else [f"z >= {self.above_z:g} m"]
        if self.box is not None:
            axes = ", ".join(
                f"{a} in [{lo:g}, {hi:g}]" for a, lo, hi in zip("xyz", *self.box, strict=True)
            )
            parts.append(f"{axes} m")
        return " and ".join(parts)


def _floats(value: object, shape: tuple[int, ...]) -> FloatArray | None:
    """``value`` as finite float64 numbers of ``shape``, or None if it is not that (text and
    booleans are not numbers here)."""
    try:
        given = np.asarray(value)
    except (TypeError, ValueError):
        return None
    if given.dtype.kind not in "iuf" or given.shape != shape:
        return None
    out = given.astype(np.float64)
    return out if bool(np.all(np.isfinite(out))) else None


def pose_constraints(
    chain: Chain,
    ranges: Mapping[str, Sequence[float]] | None = None,
    above_z: float | None = None,
    box: Sequence[Sequence[float]] | None = None,
) -> PoseConstraints:
    """The constraints, checked against ``chain`` (see :func:`plan_poses`).

    Raises:
        InputError: a joint name the chain does not have (naming the nearest); a sub-range
            that is not two finite numbers, whose low end is not below its high end, or that
            leaves the joint's limits; an ``above_z`` that is not a finite number; a box that is
            not two finite corners ``(x, y, z)``, or whose lower corner is not below the upper
            in each axis.
    """
    limits = sampling_chain(chain).limits
    assert limits is not None and chain.limits is not None
    limits = limits.copy()
    ranged = np.zeros(chain.n_joints, dtype=bool)
    if ranges is not None:
        if not isinstance(ranges, Mapping):
            raise InputError(
                "ranges must map joint names to (low, high) in rad or m, e.g. "
                f"{{'elbow_joint': (0.0, 2.5)}}, got {type(ranges).__name__}"
            )
        names = list(chain.joint_names)
        for name, value in ranges.items():
            if name not in names:
                raise InputError(
                    f"ranges: no joint {name!r} in the chain; {did_you_mean(name, names)}"
                )
            k = names.index(name)
            pair = _floats(value, (2,))
            if pair is None:
                raise InputError(
                    f"ranges[{name!r}] must be (low, high), two finite numbers in rad or m, "
                    f"got {value!r}"
                )
            lo, hi = (float(v) for v in pair)
            joint_lo, joint_hi = (float(v) for v in chain.limits[k])
            if not lo < hi:
                raise InputError(f"ranges[{name!r}] = ({lo:g}, {hi:g}): give low below high")
            if lo < joint_lo or hi > joint_hi:
                unit = "rad" if chain.joint_types[k] == "revolute" else "m"
                raise InputError(
                    f"ranges[{name!r}] = ({lo:g}, {hi:g}) is not within the joint's limits "
                    f"[{joint_lo:.6g}, {joint_hi:.6g}] {unit}: give a sub-range of them"
                )
            limits[k] = lo, hi
            ranged[k] = True
    height = None
    if above_z is not None:
        z = _floats(above_z, ())
        if z is None:
            raise InputError(f"above_z must be a finite height in m, got {above_z!r}")
        height = float(z)
    corners = None
    if box is not None:
        corners = _floats(box, (2, 3))
        if corners is None:
            raise InputError(
                "box must be ((xmin, ymin, zmin), (xmax, ymax, zmax)), finite numbers in m, "
                f"got {box!r}"
            )
        for axis, lo, hi in zip("xyz", *corners, strict=True):
            if not lo < hi:
                raise InputError(
                    f"box: {axis}min {lo:g} is not below {axis}max {hi:g}; give the lower "
                    "corner, then the upper: ((xmin, ymin, zmin), (xmax, ymax, zmax)), m"
                )
    return PoseConstraints(limits, ranged, height, corners)


def draw_candidates(
    chain: Chain,
    constraints: PoseConstraints,
    count: int,
    *,
    seed: int = 0,
    want: int | None = None,
) -> tuple[FloatArray, int]:
    """Random configurations within ``constraints.limits`` that the constraints admit.

    ``count`` are drawn (uniform per joint), then, while fewer than ``want`` (default
    ``count``) of those drawn are admitted, ``count`` more, up to 200,000 (or ``count``) in all.
    Without a height or box the first draw is returned as it is: the same configurations as
    :func:`~poekin.verification.verify.sample_joint_values` of the sampling chain.

    Returns:
        ``(K, dof)`` the admitted configurations in the order drawn (rad, m), and how many
        were drawn.
    """
    sampling = dataclasses.replace(chain, limits=constraints.limits)
    want = count if want is None else want
    kept: list[FloatArray] = []
    total, drawn, batch = 0, 0, 0
    while True:
        batch_seed = (
            seed if batch == 0 else int(np.random.SeedSequence([seed, batch]).generate_state(1)[0])
        )
        q = sample_joint_values(sampling, count, seed=batch_seed, within_limits=True)
        q = q[constraints.admits(chain, q)]
        kept.append(q)
        total, drawn, batch = total + len(q), drawn + count, batch + 1
        if total >= want or drawn + count > max(_MAX_DRAWN, count) or count == 0:
            break
    return np.concatenate(kept), drawn


@dataclasses.dataclass(frozen=True)
class PosePlan:
    """Planned poses, and the candidates they were chosen from.

    Attributes:
        q: ``(n, dof)`` the poses to measure (rad, m), in the order picked.
        constraints: what the candidates met (:func:`pose_constraints`).
        drawn: random configurations drawn within the limits (and the sub-ranges).
        kept: those of them the height and the box admit, the candidates chosen from (all
            drawn without them).
    """

    q: FloatArray
    constraints: PoseConstraints
    drawn: int
    kept: int


def plan_poses(
    model: Chain | str | os.PathLike[str] | LoadedModel,
    n: int,
    *,
    frame: str | None = None,
    measure: Measure = "pose",
    candidates: int | None = None,
    seed: int = 0,
    ranges: Mapping[str, Sequence[float]] | None = None,
    above_z: float | None = None,
    box: Sequence[Sequence[float]] | None = None,
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
        ranges: joint name to ``(low, high)`` (rad, m), within the joint's limits: those
            joints' candidates are drawn from there (a revolute joint's as given, even wider
            than a turn); the other joints' from their limits.
        above_z: keep only the candidates whose end frame's origin is this high or higher: its
            z in the chain's base (world) frame, m (e.g. ``0.05`` above the table the base
            stands on).
        box: ``((xmin, ymin, zmin), (xmax, ymax, zmax))``, m, in the chain's base frame: keep
            only the candidates whose end frame's origin lies inside it (edges included).
        progress: called with the number of poses picked so far, after each (a progress bar).

    With ``above_z`` or ``box``, the candidates that miss them are dropped before the greedy
    choice; while fewer than 2,000 (or than ``candidates``, if fewer) are left, ``candidates``
    more are drawn, up to 200,000 configurations in all. Without any constraint the plan is the
    same as before they existed, for the same seed. :func:`make_plan` also says how many
    candidates were drawn and kept.

    Raises:
        InputError: ``n`` too small to identify the parameters or above :data:`MAX_POSES`,
            ``candidates`` below ``n``, a constraint that is malformed or outside the joint
            limits (:func:`pose_constraints`), or fewer than ``n`` candidates left (saying how
            many, and what to relax).
    """
    return make_plan(
        model,
        n,
        frame=frame,
        measure=measure,
        candidates=candidates,
        seed=seed,
        ranges=ranges,
        above_z=above_z,
        box=box,
        progress=progress,
    ).q


def make_plan(
    model: Chain | str | os.PathLike[str] | LoadedModel,
    n: int,
    *,
    frame: str | None = None,
    measure: Measure = "pose",
    candidates: int | None = None,
    seed: int = 0,
    ranges: Mapping[str, Sequence[float]] | None = None,
    above_z: float | None = None,
    box: Sequence[Sequence[float]] | None = None,
    progress: Callable[[int], None] | None = None,
) -> PosePlan:
    """:func:`plan_poses`, with the constraints and how many candidates were drawn and kept."""
    from poekin.calibration.identify import minimum_poses, recommended_poses

    with one_thread():  # small matrices: see poekin._blas
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
        constraints = pose_constraints(chain, ranges, above_z, box)
        default = min(max(_MIN_CANDIDATES, _CANDIDATES_PER_POSE * n), max(_MAX_CANDIDATES, n))
        count = default if candidates is None else candidates
        count = whole_number(count, "candidates", n)
        if count > MAX_CANDIDATES:
            raise InputError(_too_many_candidates(count))
        pool, drawn = draw_candidates(
            chain, constraints, count, seed=seed, want=min(count, _ENOUGH_CANDIDATES)
        )
        if len(pool) < n:
            raise InputError(_too_few(constraints, len(pool), drawn, n))
        q = _greedy(cm, pool, n, progress)
        return PosePlan(q, constraints, drawn, len(pool))


def _too_many_candidates(count: int) -> str:
    return (
        f"{count:,} candidates: plan from at most {MAX_CANDIDATES:,} (each pose picked costs a "
        "pass over them, and each holds some 10 KB); the default, "
        f"{_CANDIDATES_PER_POSE} per pose up to {_MAX_CANDIDATES:,}, is enough"
    )


def _too_few(constraints: PoseConstraints, kept: int, drawn: int, n: int) -> str:
    """The message for a plan whose constraints left fewer than ``n`` candidates."""
    within = "within the joint limits" + (" and ranges" if constraints.ranged.any() else "")
    return (
        f"only {kept:,} of {drawn:,} random configurations {within} put the end frame at "
        f"{constraints.region_text()}, too few for {n} poses: ask for a lower height, a wider "
        "box, wider joint ranges (or none), or fewer poses"
    )


def _greedy(
    cm: CalibrationModel, pool: FloatArray, n: int, progress: Callable[[int], None] | None
) -> FloatArray:
    """``(n, dof)`` of the ``(C, dof)`` candidates ``pool``, picked one at a time for the most
    gain in ``log det`` of the information (the module's docstring)."""
    count = len(pool)
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
