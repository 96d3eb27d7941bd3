"""The fit: register, then Levenberg-Marquardt over the identifiable combinations.

Steps (:func:`fit`):

1. **Register.** The measuring frame may be anywhere: the measured positions are registered to
   the model's (Kabsch: the rotation and shift that fit them best in least squares), with the
   measured point's offset from the model's end frame solved in turn, a few rounds; with full
   poses the tool's turn is the mean of what is left.
2. **Levenberg-Marquardt** on the weighted residuals, with the analytic PoE Jacobian
   (:meth:`CalibrationModel.jacobian`): the base is updated as a pose, the other corrections
   additively in the model's own coordinates (so the fixed ones stay exactly 0). poekin's own
   solver rather than ``scipy.optimize.least_squares``: it steps on the base's pose, restricts
   every step to the identifiable subspace, reweights poses for a robust loss, and needs no
   SciPy; for this small, well-started problem (30 parameters, a few hundred residuals) it
   converges in a few iterations. A trial step costs one FK (its partial products), which
   the Jacobian reuses when the step is accepted. The fit has converged when a step would
   lower the cost by less than ``1e-12`` of it (it would move the corrections by some 1e-5
   of their standard errors), or moves every one by less than ``1e-11`` of its prior
   (noise-free data, whose cost has no floor).
3. **Weights.** Position residuals are divided by ``sigma_pos`` (m), orientation residuals by
   ``sigma_ori`` (rad). Either not given is estimated from the residuals (variance
   components: each group's residual sum of squares over its degrees of freedom, the traces of
   the hat matrix taken off), and the fit repeated until they settle. An estimate is never
   below 1e-6 (m or rad, :data:`_SIGMA_FLOOR`): exact data in one group (orientations from a
   simulation) must not weigh the other group out of the fit.
4. **What the data see.** With the base profiled out, the robot's corrections (in units of
   ``prior_m`` and ``prior_rad``, the size of the differences a robot may have from its model)
   are split by the SVD of the weighted Jacobian. A numerically null combination is not
   fitted: it keeps the model's value. One whose standard error would exceed one prior unit
   (singular value below the residual sigma) is weakly determined: it is fitted with a prior
   that pulls it toward the model's value (a standard deviation of :data:`_PRIOR_SPREAD` prior
   units), so that it moves only as far as the data say, and noise is never fitted as
   geometry; the others are identified. The fit is repeated in the subspace that is seen. A
   fixed cut at one prior unit kept a point 2 mm from joint 6's axis at the model's values and
   predicted 1.4 to 1.6 times worse than a plain fit (issue 26); this way it predicts within
   0.1% of the plain fit or better where the data tell a little.
5. **Held out** (:func:`leave_out`): each fold's poses predicted by the fit to the others,
   by the exact leave-fold-out formula of the problem linearised at the whole fit.
6. **Robust loss**: poses are reweighted by their normalised residual ``u`` (RMS over their
   numbers, in sigmas; the sigmas then from the median absolute residual), iteratively
   (IRLS), as SciPy's losses of the same names with ``f_scale`` in sigmas: ``huber`` and
   ``soft_l1`` bound an outlier's pull, ``cauchy`` lets it fade (best for gross outliers).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.calibration.model import CalibrationModel, Geometry, State, rotations
from poekin.errors import InputError

__all__ = ["LOSSES", "Fit", "Loss", "fit", "leave_out", "register", "residuals"]

FloatArray = NDArray[np.float64]
Loss = Literal["linear", "huber", "soft_l1", "cauchy"]
LOSSES: tuple[Loss, ...] = ("linear", "huber", "soft_l1", "cauchy")

_MAX_ITER = 60
_STEP_TOL = 1e-11  # stop when a step moves every correction by less than this many prior units
_COST_TOL = 1e-12  # or would lower the cost by less than this part of it
_NULL = 1e-9  # singular values below this times the largest are null
_NULL_GRAM = 1e-12  # likewise a normal matrix's eigenvalues (rounded to about 1e-16 of it)
_PRIOR_SPREAD = 2.0  # a weakly determined combination's prior standard deviation, in prior units
_SIGMA_ROUNDS = 6
_SIGMA_SETTLED = 1e-3  # relative change of the sigmas that ends the rounds
# m or rad: an estimated sigma is at least this. No tracker or camera measures better, and
# exact numbers (a simulation, a rounding-free export) would otherwise get a sigma near 0 and
# weights that drown the other group: with exact orientations and 0.1 mm of position noise
# the fit identified 18 of the UR5e's 30 parameters and missed by 6 mm (issue 26)
_SIGMA_FLOOR = 1e-6
_MAD = 1.482602218505602  # sigma of a normal distribution per median absolute deviation
_REGISTER_ROUNDS = 6  # registration: rounds of Kabsch and the measured point's offset
_REGISTERED = 1e-5  # m: a round that moves the point less ends them (the fit does the rest)
_FREED = 1e-6  # m or rad: a step of to_free this small leaves ~1e-12 (the fit does the rest)


@dataclasses.dataclass(frozen=True)
class Fit:
    """What :func:`fit` found.

    Attributes:
        state: the fitted base and corrections.
        basis: ``(F, K)`` the combinations of the free corrections that were fitted
            (columns, in the corrections' own units; the base's 6 included first, then the
            robot's in the order of :attr:`directions`): all that the data see.
        identified: how many of the robot combinations of :attr:`basis` the data identify
            (standard error within one prior unit); the others are weakly determined, and
            shrunk toward the model's values by their prior (one prior unit).
        prior_hessian, prior_gradient: ``(K, K)`` and ``(K,)`` the prior's part of the normal
            equations at :attr:`state`, in the coordinates of :attr:`basis`.
        singular: the singular values of the robot part (before truncation), in prior units
            and residual sigmas (the base profiled out).
        directions: ``(R, R)`` the matching right singular vectors (rows), over the free
            robot corrections (in prior units).
        sigma_pos, sigma_ori: the weights used (m, rad): given, or estimated.
        sigma: the residual sigma of the weighted fit (about 1 when the weights are right).
        weights: ``(N,)`` the robust loss's weight of each pose (all 1 for ``linear``).
        poses: ``(N, 4, 4)`` the fitted model's poses, in the measuring frame.
        residuals: ``(N, m)`` measured minus fitted: the rotation ``log(R_meas R^T)`` (rad;
            pose data only), then the position (m).
        jacobian: ``(N, m, F)`` the derivatives of the measured numbers at ``state`` over the
            free corrections (:meth:`~.model.CalibrationModel.jacobian`'s rows and columns).
        cov: ``(F, F)`` covariance of the free corrections (the base's as a turn and a shift).
        iterations: Levenberg-Marquardt iterations, all rounds together.
        converged: whether the last round's steps became small.
    """

    state: State
    basis: FloatArray
    identified: int
    prior_hessian: FloatArray
    prior_gradient: FloatArray
    singular: FloatArray
    directions: FloatArray
    sigma_pos: float
    sigma_ori: float
    sigma: float
    weights: FloatArray
    poses: FloatArray
    residuals: FloatArray
    jacobian: FloatArray
    cov: FloatArray
    iterations: int
    converged: bool

    @property
    def row_sigmas(self) -> FloatArray:
        """``(m,)`` each measured number's sigma: orientation (rad) then position (m), or the
        position's alone."""
        pose = self.residuals.shape[1] == 6
        return np.repeat([self.sigma_ori, self.sigma_pos] if pose else [self.sigma_pos], 3)

    @property
    def scale(self) -> FloatArray:
        """``(N, m)`` what each measured number is multiplied by in the fit: one over its
        sigma, times the square root of its pose's robust weight."""
        return np.asarray(np.sqrt(self.weights)[:, None] / self.row_sigmas, dtype=np.float64)

    def weighted(self) -> tuple[FloatArray, FloatArray]:
        """The residuals ``(N, m)`` and their Jacobian ``(N, m, F)`` as the fit weighs them
        (times :attr:`scale`)."""
        return self.residuals * self.scale, self.jacobian * self.scale[:, :, None]


def residuals(model: CalibrationModel, T: FloatArray, measured: FloatArray) -> FloatArray:
    """``(N, m)`` measured minus model: the rotation ``log(R_meas R^T)`` (rad; pose data
    only), then the position (m), in the measuring frame."""
    dp = measured[:, :3, 3] - T[:, :3, 3] if measured.ndim == 3 else measured - T[:, :3, 3]
    if model.measure == "position":
        return np.asarray(dp, dtype=np.float64)
    dR = measured[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2)
    return np.concatenate([lie.log_so3(dR), dp], axis=1)


def register(points: FloatArray, measured: FloatArray) -> FloatArray:
    """``(4, 4)`` the rigid motion that best maps ``points`` ``(N, 3)`` onto ``measured``
    (least squares; Kabsch/Horn via the SVD of the cross-covariance)."""
    cp, cm = points.mean(axis=0), measured.mean(axis=0)
    H = (points - cp).T @ (measured - cm)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d if d != 0 else 1.0]) @ U.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = cm - R @ cp
    return T


def initial_state(model: CalibrationModel, q: FloatArray, measured: FloatArray) -> State:
    """Register the model to the measurements (step 1 of the module docstring)."""
    shift = list(model.tool_shift_index)
    turn = list(model.tool_turn_index)
    p_meas = measured[:, :3, 3] if measured.ndim == 3 else measured
    # the model's flange (its end frame less its home pose): the tool's corrections leave it
    P, _ = model.products(model.nominal(), q)
    F_R, F_p = P[:, -1, :3, :3], P[:, -1, :3, 3]
    R_M, p_M = model.chain.home[:3, :3], model.chain.home[:3, 3]
    R_end = F_R @ R_M  # (N, 3, 3) the end frame's rotation before the tool's turn
    R_tool, t = np.eye(3), np.zeros(3)  # the tool's turn and shift (in the end frame)

    def points() -> FloatArray:  # the measured point: P_n (p_M + R_M t)
        return np.asarray(R_end @ t + (F_R @ p_M) + F_p, dtype=np.float64)

    for _ in range(_REGISTER_ROUNDS):
        base = register(points(), p_meas)
        R_B = base[:3, :3]
        if turn:  # the tool's turn: the chordal mean of what is left
            left = np.swapaxes(R_B @ R_end @ R_tool, 1, 2) @ measured[:, :3, :3]
            U, _, Vt = np.linalg.svd(left.mean(axis=0))
            R_tool = R_tool @ U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt
        # the point's offset in the end frame: p = B P_n (p_M + R_M t)
        A = R_B @ R_end
        b = p_meas - points() @ R_B.T - base[:3, 3]
        dt = np.linalg.lstsq(A.reshape(-1, 3), b.reshape(-1), rcond=None)[0]
        t = t + dt
        if np.linalg.norm(dt) < _REGISTERED:
            break
    x = np.zeros(model.n_params)
    x[shift] = t
    if turn:
        x[turn] = lie.log_so3(R_tool)
    return to_free(model, State(register(points(), p_meas), x), q)


def to_free(model: CalibrationModel, state: State, q: FloatArray) -> State:
    """The same robot (the same poses at ``q``) with the corrections that are not free at 0:
    Gauss-Newton on the free ones towards the poses of ``state`` (the dropped corrections are
    redundant, so the minimal set reproduces them exactly)."""
    dropped = [r.param for r in model.redundant]
    if not np.any(state.x[dropped]):
        return state
    target = model.poses(state, q)
    x = state.x.copy()
    x[dropped] = 0.0
    free = list(model.free)
    current = State(state.base, x)
    for _ in range(_MAX_ITER):
        T, D = model.jacobian(current, q)
        turn = lie.log_so3(target[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2))
        r = np.concatenate([turn, target[:, :3, 3] - T[:, :3, 3]], axis=1).reshape(-1)
        J = D[:, :, free].reshape(-1, len(free))
        dx = _solve(J.T @ J, J.T @ r)
        current = _retract(model, current, free, dx)
        if np.max(np.abs(dx)) < _FREED:
            break
    return current


def _solve(H: FloatArray, g: FloatArray) -> FloatArray:
    """``H^+ g`` for a symmetric positive semi-definite ``H`` ``(F, F)``: the normal equations
    of a least-squares step (minimum norm where ``H`` is singular)."""
    return np.asarray(np.linalg.lstsq(H, g, rcond=None)[0], dtype=np.float64)


def _retract(model: CalibrationModel, state: State, free: list[int], dx: FloatArray) -> State:
    """The state moved by ``dx`` over the free corrections: the base (its first 6) turned about
    its own axes and shifted along them, the others added."""
    step = np.zeros(model.n_params)
    step[free] = dx
    G = np.eye(4)
    G[:3, :3] = rotations(step[:3])
    G[:3, 3] = step[3:6]
    x = state.x + step
    x[:6] = 0.0
    return State(state.base @ G, x)


def _robust(loss: Loss, u: FloatArray, f_scale: float) -> FloatArray:
    """Each pose's weight for its normalised residual ``u`` (IRLS)."""
    if loss == "huber":
        return np.minimum(1.0, f_scale / np.maximum(u, 1e-300))
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + (u / f_scale) ** 2)
    if loss == "cauchy":
        return 1.0 / (1.0 + (u / f_scale) ** 2)
    return np.ones_like(u)


@dataclasses.dataclass(frozen=True, eq=False)
class _Point:
    """The model at one state on the data: its poses, residuals ``(N, m)`` (rad, m) and,
    when first asked, its derivatives over the free corrections ``(N, m, F)`` (from the same
    partial products: a trial step that is accepted costs no second FK)."""

    problem: _Problem
    state: State
    poses: FloatArray
    raw: FloatArray
    products: FloatArray
    geometry: Geometry

    @functools.cached_property
    def derivatives(self) -> FloatArray:
        p = self.problem
        _, D = p.model.derivatives(self.state, self.products, self.geometry)
        return np.asarray(p.model.measured(D)[:, :, p.free], dtype=np.float64)


@dataclasses.dataclass(frozen=True)
class _Problem:
    """What stays fixed while fitting: the data, the free corrections and the loss."""

    model: CalibrationModel
    q: FloatArray
    measured: FloatArray
    free: list[int]
    units: FloatArray
    loss: Loss
    f_scale: float
    # (w, R): the weakly determined robot combinations (rows over the free robot corrections,
    # in prior units), each pulled toward the model's value with one prior unit of standard
    # deviation (step 4); none in the first fit
    prior: FloatArray | None = None

    def pulled(self, state: State) -> FloatArray:
        """``(w,)`` the weak combinations' values at ``state`` (prior units; 0 without)."""
        if self.prior is None:
            return np.zeros(0)
        return np.asarray(
            self.prior @ (state.x[self.free[6:]] / self.units[6:]) / _PRIOR_SPREAD,
            dtype=np.float64,
        )

    def prior_rows(self, state: State, Z: FloatArray | None) -> tuple[FloatArray, FloatArray]:
        """The prior's residuals ``b_p`` ``(w,)`` and their Jacobian ``A_p`` ``(w, K)`` as
        :meth:`linearise` gives the data's: a step ``dy`` leaves ``b_p - A_p dy``."""
        if self.prior is None:
            return np.zeros(0), np.zeros((0, len(self.free) if Z is None else Z.shape[1]))
        assert Z is not None  # a prior is found with the basis it is fitted in
        A_p = self.prior @ (Z[6:] / self.units[6:, None]) / _PRIOR_SPREAD
        return -self.pulled(state), np.asarray(A_p, dtype=np.float64)

    def at(self, state: State) -> _Point:
        P, geo = self.model.products(state, self.q)
        T = state.base @ P[:, -1] @ geo.home
        return _Point(self, state, T, residuals(self.model, T, self.measured), P, geo)

    def cost(self, point: _Point, sig: FloatArray) -> float:
        r = point.raw / sig
        w = _robust(self.loss, np.sqrt(np.mean(r * r, axis=1)), self.f_scale)
        pulled = self.pulled(point.state)
        return float(np.sum(w[:, None] * r * r) + pulled @ pulled)

    def linearise(
        self, point: _Point, sig: FloatArray, Z: FloatArray | None
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Weighted residuals ``(N, m)``, the robust weights ``(N,)`` and the Jacobian ``A``
        ``(N m, K)`` of the weighted residuals (times the square roots of the robust weights)
        with respect to ``-dy``, ``dx = Z dy`` (``Z`` None: every free correction): a step
        leaves ``sqrt(w) r - A dy``."""
        r = point.raw / sig
        w = _robust(self.loss, np.sqrt(np.mean(r * r, axis=1)), self.f_scale)
        J = point.derivatives * (np.sqrt(w)[:, None, None] / sig[:, None])
        A = J.reshape(-1, J.shape[-1])
        return r, w, (A if Z is None else A @ Z)

    def lm(self, point: _Point, sig: FloatArray, Z: FloatArray | None) -> tuple[_Point, int, bool]:
        """Levenberg-Marquardt in ``dx = Z dy`` (Marquardt's scaling: the damping grows the
        diagonal of the normal equations). Converged when a step would lower the cost by less
        than ``_COST_TOL`` of it (it would move the fit by a negligible part of its standard
        errors), or moves every correction by less than ``_STEP_TOL`` prior units (noise-free
        data, whose cost has no floor)."""
        lam = 1e-4
        r, w, A = self.linearise(point, sig, Z)
        cost = self.cost(point, sig)
        for it in range(1, _MAX_ITER + 1):
            b = (r * np.sqrt(w)[:, None]).reshape(-1)
            b_p, A_p = self.prior_rows(point.state, Z)
            H, g = A.T @ A + A_p.T @ A_p, A.T @ b + A_p.T @ b_p
            # Marquardt's scaling, as a unit diagonal: (H_s + lam I) y = g_s, dy = s y
            s = 1.0 / np.sqrt(np.maximum(np.diag(H), 1e-300))
            Hs, gs, eye = H * s[:, None] * s[None, :], g * s, np.eye(len(g))
            first = True
            while True:
                dy = np.linalg.solve(Hs + lam * eye, gs) * s
                if first and lam <= 1.0 and float(dy @ (2.0 * g - H @ dy)) <= _COST_TOL * cost:
                    return point, it, True
                first = False
                dx = dy if Z is None else Z @ dy
                small = float(np.max(np.abs(dx) / self.units, initial=0.0)) < _STEP_TOL
                trial = self.at(_retract(self.model, point.state, self.free, dx))
                cost_t = self.cost(trial, sig)
                if cost_t <= cost or small:
                    break
                lam *= 4.0
                if lam > 1e14:  # no step lowers the cost: a minimum, to rounding
                    return point, it, True
            point, cost = trial, cost_t
            if small:
                return point, it, True
            lam = max(lam / 3.0, 1e-12)
            r, w, A = self.linearise(point, sig, Z)
        return point, _MAX_ITER, False

    def sigmas(
        self, point: _Point, sig: FloatArray, Z: FloatArray | None, given: tuple[float | None, ...]
    ) -> FloatArray:
        """The weights estimated from the residuals (step 3): per group of rows (orientation,
        position), the weighted residual sum of squares over its degrees of freedom (the
        robust losses: the median absolute residual)."""
        r, w, A = self.linearise(point, sig, Z)
        m = r.shape[1]
        groups = [np.arange(m) < 3] if m == 6 else []
        groups.append(np.arange(m) >= (3 if m == 6 else 0))
        traces = _hat_traces(A.reshape(len(r), m, -1), groups)
        raw = r * sig
        out = sig.copy()
        for g, tr, fixed in zip(groups, traces, given, strict=True):
            if fixed is not None:
                continue
            count = float(g.sum()) * len(r)
            dof = max(count - tr, 1.0)
            if self.loss == "linear":
                s = float(np.sqrt(np.sum(w[:, None] * raw[:, g] ** 2) / dof))
            else:
                s = _MAD * float(np.median(np.abs(raw[:, g]))) * float(np.sqrt(count / dof))
            out[g] = max(s, _SIGMA_FLOOR)
        return np.asarray(out, dtype=np.float64)

    def settle(
        self,
        point: _Point,
        sig: FloatArray,
        Z: FloatArray | None,
        given: tuple[float | None, ...],
    ) -> tuple[_Point, FloatArray, int, bool]:
        """Fit, re-estimating the weights not given until they settle."""
        iterations = 0
        for _ in range(_SIGMA_ROUNDS):
            point, it, converged = self.lm(point, sig, Z)
            iterations += it
            if all(s is not None for s in given):
                break
            new = self.sigmas(point, sig, Z, given)
            changed = float(np.max(np.abs(new / sig - 1.0)))
            sig = new
            if changed < _SIGMA_SETTLED:
                break
        else:
            point, it, converged = self.lm(point, sig, Z)
            iterations += it
        return point, sig, iterations, converged


def _problem(
    model: CalibrationModel,
    q: FloatArray,
    measured: FloatArray,
    loss: Loss,
    f_scale: float,
    prior_m: float,
    prior_rad: float,
) -> _Problem:
    if loss not in LOSSES:
        raise InputError(f"unknown loss {loss!r}; use one of {', '.join(LOSSES)}")
    free = list(model.free)
    return _Problem(model, q, measured, free, model.units(free, prior_m, prior_rad), loss, f_scale)


def fit(
    model: CalibrationModel,
    q: FloatArray,
    measured: FloatArray,
    *,
    sigma_pos: float | None,
    sigma_ori: float | None,
    loss: Loss,
    f_scale: float,
    prior_m: float,
    prior_rad: float,
    start: State | None = None,
) -> Fit:
    """Fit ``model`` to encoder readings ``q`` ``(N, n)`` and measurements ``(N, 4, 4)`` or
    ``(N, 3)`` (validated by the caller); see the module docstring."""
    problem = _problem(model, q, measured, loss, f_scale, prior_m, prior_rad)
    free, units = problem.free, problem.units
    pose = model.measure == "pose"
    given = (sigma_ori, sigma_pos) if pose else (sigma_pos,)
    guess = [1e-4 if s is None else float(s) for s in given]
    sig = np.repeat(guess, 3)
    point = problem.at(initial_state(model, q, measured) if start is None else start)
    point, sig, iterations, converged = problem.settle(point, sig, None, given)
    r, w, A = problem.linearise(point, sig, None)
    Zn, singular, directions, identified = _identifiable(
        A, units, _residual_sigma(r, w, A.shape[1])
    )
    Z = np.eye(len(free))
    if Zn.shape[1] < len(free) or identified < Zn.shape[1] - 6:
        # keep only the part of what was fitted that the data see, then fit within it, the
        # weakly determined combinations pulled toward the model's values by their prior
        Z = Zn
        robot = Z[6:, 6:] / units[6:, None]  # orthonormal columns, in prior units
        y = point.state.x[free[6:]] / units[6:]
        x = point.state.x.copy()
        x[free[6:]] = (robot @ (robot.T @ y)) * units[6:]
        weak = directions[identified : Zn.shape[1] - 6]
        problem = dataclasses.replace(problem, prior=weak if len(weak) else None)
        point = problem.at(State(point.state.base, x))
        point, sig, more, converged = problem.settle(point, sig, Z, given)
        iterations += more
        r, w, A = problem.linearise(point, sig, Z)
    b_p, A_p = problem.prior_rows(point.state, Z)
    sigma = _residual_sigma(r, w, A.shape[1] - len(b_p))
    cov = Z @ (sigma**2 * np.linalg.pinv(A.T @ A + A_p.T @ A_p, hermitian=True)) @ Z.T
    return Fit(
        state=point.state,
        basis=Z,
        identified=identified,
        prior_hessian=A_p.T @ A_p,
        prior_gradient=A_p.T @ b_p,
        singular=singular,
        directions=directions,
        sigma_pos=float(sig[-1]),
        sigma_ori=float(sig[0]) if pose else float("nan"),
        sigma=sigma,
        weights=w,
        poses=point.poses,
        residuals=point.raw,
        jacobian=point.derivatives,
        cov=cov,
        iterations=iterations,
        converged=converged,
    )


def leave_out(fitted: Fit, fold: NDArray[np.int_]) -> tuple[FloatArray, FloatArray]:
    """Each pose's position and orientation errors (m, rad; NaN for positions-only data)
    predicted by a fit to the other folds (``fold`` ``(N,)`` numbers each pose's fold).

    The exact leave-fold-out solution of the problem linearised at the whole fit ``fitted``,
    with its weights and identifiable combinations: the fold's rows leave the normal equations
    (``H - A_f^T A_f``, ``g - A_f^T b_f``; ``g = 0`` at the whole fit's minimum), the step
    ``dy`` they give is the other folds' fit (one Gauss-Newton step from the whole fit, which
    is within a few standard errors of it), and the fold's predicted residuals are
    ``r_f - A_f dy``. What the linearisation leaves out is second order in that step: some
    1e-6 of the noise (``tests/calibration/test_calibration_fit.py`` checks it against refitting).
    """
    b, J = fitted.weighted()
    A3 = J @ fitted.basis
    N, m, K = A3.shape
    A = A3.reshape(-1, K)
    H = A.T @ A + fitted.prior_hessian
    g = A.T @ b.reshape(-1) + fitted.prior_gradient
    e = np.empty_like(b)  # the predicted residuals, weighted
    for f in np.unique(fold):
        test = fold == f
        At = A3[test].reshape(-1, K)
        dy = _solve(H - At.T @ At, g - At.T @ b[test].reshape(-1))
        e[test] = b[test] - (At @ dy).reshape(-1, m)
    e /= fitted.scale  # back to radians and metres
    pos = np.linalg.norm(e[:, -3:], axis=1)
    ori = np.linalg.norm(e[:, :3], axis=1) if m == 6 else np.full(N, np.nan)
    return pos, ori


def _hat_traces(A: FloatArray, groups: list[NDArray[np.bool_]]) -> list[float]:
    """Traces of the hat matrix ``A (A^T A)^+ A^T`` over each group of rows: ``A`` ``(N, m,
    K)``, a group a mask over the ``m`` rows of each pose. ``tr(H^+ A_g^T A_g)``, with the
    pseudo-inverse of the normal matrix ``H`` (its null directions are fitted by nothing)."""
    K = A.shape[-1]
    H = np.einsum("nmk,nml->kl", A, A)
    Hinv = np.linalg.pinv(H, rcond=_NULL_GRAM, hermitian=True)
    out = []
    for g in groups:
        Ag = A[:, g].reshape(-1, K)
        out.append(float(np.sum(Hinv * (Ag.T @ Ag))))
    return out


def _residual_sigma(r: FloatArray, w: FloatArray, p: int) -> float:
    """The weighted residuals' sigma, ``sqrt(sum w r^2 / (N m - p))``."""
    dof = max(r.size - p, 1)
    return float(np.sqrt(np.sum(w[:, None] * r * r) / dof))


def _identifiable(
    A: FloatArray, units: FloatArray, sigma: float
) -> tuple[FloatArray, FloatArray, FloatArray, int]:
    """The basis ``Z`` of the base and the robot combinations the data see (step 4: not
    numerically null), in the corrections' units; the robot part's singular values and right
    singular vectors (rows), in prior units; and how many of those combinations (the first)
    the data identify, their standard error within one prior unit (singular value at least
    the residual sigma): the others are weakly determined, and shrunk toward the model."""
    Ab, Ar = A[:, :6], A[:, 6:] * units[None, 6:]
    # the robot's columns less what the base's explain (the base is profiled out)
    Ar = Ar - Ab @ np.linalg.solve(Ab.T @ Ab, Ab.T @ Ar)
    _, s, Vt = np.linalg.svd(Ar, full_matrices=False)
    top = float(s[0]) if s.size else 0.0
    seen = s > _NULL * top
    n = A.shape[1]
    Z = np.zeros((n, 6 + int(seen.sum())))
    Z[:6, :6] = np.eye(6)
    Z[6:, 6:] = units[6:, None] * Vt[seen].T
    return Z, s, Vt, int(np.sum(seen & (s >= sigma)))
