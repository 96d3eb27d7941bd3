"""Analytic inverse kinematics: every solution of a 6-revolute-joint arm in closed form.

The arm's geometry is read from its screw axes (never from its name) and the pose equation
``T_world_frame = exp([S_1] q_1) ... exp([S_6] q_6) M`` is split into the subproblems of
:mod:`poekin.ik.subproblems`. Two families of arms have such a split, each with 8 solutions:

* **three parallel axes**: axes 2, 3 and 4 parallel and axes 5 and 6 meeting (Universal
  Robots' UR3 to UR20, CB3 and e-Series, whatever their link lengths). The point where axes 5
  and 6 meet fixes ``q1`` (subproblem 4: its height along the parallel axes cannot change),
  the direction of axis 6 fixes ``q2 + q3 + q4`` and ``q5`` (subproblem 4 on the circle of that
  direction, then 1), the remaining rotation ``q6`` (subproblem 1), and the planar two-link arm
  ``q3`` then ``q2`` (subproblems 3 and 1);
* **spherical wrist**: axes 4, 5 and 6 meet in one point (the wrist centre, which they do not
  move), with the first three axes in one of these arrangements: axes 2 and 3 parallel
  (PUMA, ABB, KUKA, Fanuc arms: subproblems 4, 3, 1), axes 1 and 2 meeting (subproblems 3, 2),
  or axes 2 and 3 meeting (subproblems 3, 2). The wrist angles then follow from the
  orientation (subproblem 2 on the direction of axis 6, then 1 for ``q6``).

Tolerance of the geometry test: axes count as parallel within ``GEOMETRY_TOL`` rad and as
meeting when closer than ``GEOMETRY_TOL`` times the arm's size (the largest distance from the
end frame's home position to a joint axis, ~1 m for a UR5e). The solution is exact for the
model's own axes when they meet that ideal to rounding (MuJoCo's compile of the Menagerie arms
and poekin's DH chains do: the solutions' residuals are ~1e-15); a model inside the tolerance
but not exact gets residuals up to about its deviation times its size, which ``pos_err`` and
``ori_err`` report.

Singular targets keep exact solutions, with these conventions where a family of solutions
replaces discrete ones:

* wrist singularity, spherical wrist (axes 4 and 6 aligned): only ``phi = q4 +- q6`` is
  fixed; the two wrist branches share it evenly (``q4 = +-q6 = phi / 2``) and put it all on
  ``q6`` (``q4 = 0``);
* wrist singularity, three parallel axes (``q5 = 0`` or ``pi`` puts axis 6 parallel to axes 2
  to 4): only ``q2 + q3 + q4 +- q6`` is fixed; the two wrist branches put the point where
  axes 5 and 6 meet in one plane with axes 2 and 4, nearest to and furthest from axis 2 (one
  is within reach whenever any configuration is), and ``q6`` takes the rest;
* shoulder singularity (the wrist centre on axis 1): ``q1`` is free, and the solutions have
  ``q1 = 0`` and ``q1 = pi``;
* a stretched or folded elbow, or any other tangent case: the two roots coincide and come
  back twice.
"""

from __future__ import annotations

import dataclasses
import functools
import weakref
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _pose
from poekin._poe import real_array
from poekin.errors import AnalyticIKError, InputError
from poekin.ik import subproblems as sp
from poekin.ik._angles import nearest_turns, within_limits, wrap_into_limits
from poekin.ik.subproblems import CosSin, add, dot, lift, rotate, sub

try:
    from poekin.kernel import _kernel  # type: ignore[attr-defined]
except ImportError:  # built without a C compiler: the NumPy reference serves
    _kernel = None

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.ik.numerical import IKResult

__all__ = [
    "GEOMETRY_TOL",
    "NEAR_TOL",
    "Geometry",
    "IKSolutions",
    "geometry",
    "ik_all",
    "nearest_branch",
    "nearest_geometry",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Vec = tuple[float, float, float]

#: Tolerance of the geometry test: radians between axes counted as parallel, and the fraction
#: of the arm's size (:attr:`Geometry.size`) between axes counted as meeting.
GEOMETRY_TOL = 1e-10

# Subproblem tolerances, relative to the arm's size (lengths) or 1 (directions): a branch
# counts as existing when its equation is missed by less than _EXISTS (so an unreachable
# target's nearest point is accepted only within 1e-12 of the size), and a circle shorter than
# _DEGENERATE is a point (the singular conventions; the residual they leave is below it).
_EXISTS = sp.TOL
_DEGENERATE = 1e-13

_ENDS = np.array([1.0, -1.0])  # a turn and the opposite one
_EVEN = np.array([True, False])  # the singular wrist's roots: phi shared evenly, all on q6

# A target's rotation block must be orthonormal to this (as poekin.chain.check_pose).
_RIGID_TOL = 1e-6


@dataclasses.dataclass(frozen=True, eq=False)
class IKSolutions:
    """Every closed-form solution of each target (:meth:`poekin.Chain.ik_all`). Immutable.

    Attributes:
        q: ``(..., k, 6)`` joint values (rad), ``k`` fixed by the geometry (8 for every
            supported one). Each angle is brought into its joint limits by whole turns where
            a turn does that, else left in ``(-pi, pi]``. Where ``valid`` is False, ``q``
            holds that branch's least-squares values: the target moved to the nearest point
            the branch reaches (a target out of reach), or a solution outside the limits;
            finite either way.
        valid: ``(..., k)`` True where the branch solves the target exactly (to 1e-12 of the
            arm's size) and lies within the limits.
        geometry: the :class:`Geometry` that was solved.
        collides: ``(..., k)`` where asked for (:meth:`poekin.Chain.ik_all` with
            ``obstacles``): True where the branch's configuration has a checked pair of the
            robot's collision geometry (with itself or an obstacle) closer than the margin;
            else None.
    """

    q: FloatArray
    valid: BoolArray
    geometry: Geometry
    _chain: Chain = dataclasses.field(repr=False)
    _targets: FloatArray = dataclasses.field(repr=False)
    collides: BoolArray | None = None

    @functools.cached_property
    def pos_err(self) -> FloatArray:
        """``(..., k)`` distance (m) between each target's position and ``chain.fk(q)``'s
        (computed on first access)."""
        return self._errors[0]

    @functools.cached_property
    def ori_err(self) -> FloatArray:
        """``(..., k)`` geodesic angle (rad) between each target's rotation and
        ``chain.fk(q)``'s (computed on first access)."""
        return self._errors[1]

    @functools.cached_property
    def _errors(self) -> tuple[FloatArray, FloatArray]:
        """The angle from ``|R_a - R_b|_F = 2 sqrt(2) sin(angle / 2)``, accurate near 0."""
        got = self._chain.fk(self.q)
        T = self._targets[..., None, :, :]
        pos = np.linalg.norm(got[..., :3, 3] - T[..., :3, 3], axis=-1)
        frob = np.sqrt(np.sum((got[..., :3, :3] - T[..., :3, :3]) ** 2, axis=(-2, -1)))
        ori = 2.0 * np.arcsin(np.minimum(frob / np.sqrt(8.0), 1.0))
        return pos, ori


@dataclasses.dataclass(frozen=True)
class Geometry:
    """The closed-form split found for a chain (:func:`geometry`).

    Attributes:
        kind: ``"three parallel axes"`` or ``"spherical wrist"``.
        description: what was found, e.g. ``"three parallel axes (2, 3, 4), axes 5 and 6
            meet"``.
        size: the arm's size (m), the scale of the tolerances: the largest distance from the
            end frame's home position to a joint axis.
        n_solutions: ``k``, the number of branches returned per target.
        nearest: ``""`` when the chain has this geometry (to :data:`GEOMETRY_TOL`); else how
            far it is from it (``"axes 2 and 3 are not parallel: 0.07 deg; ..."``): the
            closed form is the nearest ideal geometry's, and :func:`ik_all` refines each
            branch on the chain (:func:`nearest_geometry`).
    """

    kind: str
    description: str
    size: float
    n_solutions: int
    _solve: Callable[[_Target], _Branches] = dataclasses.field(repr=False)
    _kind: int = dataclasses.field(repr=False)  # the compiled twin's split and constants
    _params: FloatArray = dataclasses.field(repr=False)
    nearest: str = ""


# --- the geometry ------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _Line:
    point: FloatArray  # (3,)
    w: FloatArray  # (3,) unit


def _angle(a: _Line, b: _Line) -> float:
    """The angle between two lines' directions, in [0, pi/2] (a line has no sense)."""
    return float(np.arctan2(np.linalg.norm(np.cross(a.w, b.w)), abs(a.w @ b.w)))


def _closest(a: _Line, b: _Line) -> tuple[FloatArray, FloatArray]:
    """The points of two non-parallel lines nearest each other."""
    n = np.cross(a.w, b.w)
    d = b.point - a.point
    nn = n @ n
    return a.point + a.w * (np.cross(d, b.w) @ n / nn), b.point + b.w * (np.cross(d, a.w) @ n / nn)


def _gap(a: _Line, b: _Line) -> float:
    """The distance between two lines that are not parallel."""
    pa, pb = _closest(a, b)
    return float(np.linalg.norm(pa - pb))


def _to_line(x: FloatArray, line: _Line) -> float:
    d = x - line.point
    return float(np.linalg.norm(d - line.w * (d @ line.w)))


def _foot(x: FloatArray, line: _Line) -> FloatArray:
    """The point of ``line`` nearest ``x``."""
    return line.point + line.w * ((x - line.point) @ line.w)


def _meet(a: _Line, b: _Line) -> FloatArray:
    pa, pb = _closest(a, b)
    return (pa + pb) / 2


def _figure(x: float) -> str:
    """Two significant digits, without an exponent from 10 up: 0.3, 3.2, 97, 1.2e-05."""
    return f"{x:.0f}" if x >= 10 else f"{x:.2g}"


def _deg(x: float) -> str:
    return f"{_figure(float(np.degrees(x)))} deg"


def _mm(x: float) -> str:
    return f"{_figure(x * 1e3)} mm apart"


class _Arm:
    """The chain's axis lines, its size, and the tests of the geometry conditions, each
    returning ``""`` when it holds or what fails, with the number."""

    def __init__(self, chain: Chain, tol: float = GEOMETRY_TOL) -> None:
        self.tol = tol  # rad, and a fraction of the size
        S = chain.screws
        self.lines = [_Line(np.cross(s[:3], s[3:]), s[:3].copy()) for s in S]
        self.home = chain.home
        p_M = chain.home[:3, 3]
        self.size = max(max(_to_line(p_M, line) for line in self.lines), 1e-9)

    def line(self, i: int) -> _Line:
        return self.lines[i - 1]

    def parallel(self, i: int, j: int) -> str:
        angle = _angle(self.line(i), self.line(j))
        return "" if angle <= self.tol else f"axes {i} and {j} are not parallel: {_deg(angle)}"

    def crossing(self, i: int, j: int) -> str:
        """Axes ``i`` and ``j`` not parallel (else the split has a circle that never turns)."""
        return (
            f"axes {i} and {j} are parallel"
            if _angle(self.line(i), self.line(j)) <= self.tol
            else ""
        )

    def meet(self, i: int, j: int) -> str:
        a, b = self.line(i), self.line(j)
        if _angle(a, b) <= self.tol:
            return f"axes {i} and {j} are parallel, not meeting"
        gap = _gap(a, b)
        return "" if gap <= self.tol * self.size else f"axes {i} and {j} do not meet: {_mm(gap)}"

    def wrist(self) -> str:
        """Axes 4, 5 and 6 through one point."""
        fails = self.meet(4, 5) or self.meet(5, 6)
        if fails:
            return fails
        gap = _to_line(_meet(self.line(4), self.line(5)), self.line(6))
        if gap <= self.tol * self.size:
            return ""
        return f"axis 6 misses the point where axes 4 and 5 meet: {_mm(gap)}"


def _describe_failure(chain: Chain, arm: _Arm, tried: list[tuple[str, str]]) -> str:
    name = chain.robot or "this chain"
    reasons = "; ".join(f"{geometry} fails: {why}" for geometry, why in tried)
    return (
        f"ik_all has no closed form for {name}: {reasons} (tolerance {arm.tol:g} rad, "
        f"{arm.tol:g} x its size {arm.size:.3g} m). Supported: three parallel axes "
        "(2, 3, 4) with axes 5 and 6 meeting (UR arms), or axes 4, 5, 6 meeting in a point "
        "with axes 2 and 3 parallel, axes 1 and 2 meeting, or axes 2 and 3 meeting; use the "
        "numerical chain.ik for other arms"
    )


_GEOMETRIES: weakref.WeakKeyDictionary[Chain, Geometry] = weakref.WeakKeyDictionary()
_NEAREST: weakref.WeakKeyDictionary[Chain, Geometry | AnalyticIKError] = weakref.WeakKeyDictionary()

#: How far from a supported geometry a chain may be (rad between axes, a fraction of the arm's
#: size between axes that should meet) for :func:`ik_all` to solve the nearest ideal geometry
#: in closed form and refine each branch on the chain itself: a calibrated arm's axes are
#: never exactly parallel (a real UR's are 0.045 to 0.086 deg off, and 0.007 to 0.038 mm).
NEAR_TOL = 1e-2


def nearest_geometry(chain: Chain) -> Geometry:
    """The closed-form split of the supported geometry nearest ``chain``: its own
    (:func:`geometry`) when it has one to :data:`GEOMETRY_TOL`, else the first supported one
    within :data:`NEAR_TOL`, whose :attr:`Geometry.nearest` says how far the chain is from it.

    Raises:
        AnalyticIKError: no supported geometry within :data:`NEAR_TOL` either (the message
            names each condition that fails exactly).
    """
    found = _NEAREST.get(chain)  # found once per chain, a refusal too
    if found is None:
        try:
            found = geometry(chain)
        except AnalyticIKError as exact:
            try:
                near = _find(chain, NEAR_TOL)
                found = dataclasses.replace(
                    near, nearest=_deviations(_Arm(chain), near.description)
                )
            except AnalyticIKError:
                six = chain.n_joints == 6 and all(t == "revolute" for t in chain.joint_types)
                beyond = f" (nor within {NEAR_TOL:g} of one, which ik_all would refine)"
                found = AnalyticIKError(f"{exact}{beyond if six else ''}")
        _NEAREST[chain] = found
    if isinstance(found, AnalyticIKError):
        raise AnalyticIKError(str(found))
    return found


def _deviations(arm: _Arm, description: str) -> str:
    """How far the chain of ``arm`` is from the geometry ``description`` names, in words."""
    checks = {
        "three parallel axes (2, 3, 4), axes 5 and 6 meet": [
            arm.parallel(2, 3), arm.parallel(2, 4), arm.meet(5, 6)
        ],
        "spherical wrist (axes 4, 5, 6 meet), axes 2 and 3 parallel": [
            arm.wrist(), arm.parallel(2, 3)
        ],
        "spherical wrist (axes 4, 5, 6 meet), axes 1 and 2 meet": [arm.wrist(), arm.meet(1, 2)],
        "spherical wrist (axes 4, 5, 6 meet), axes 2 and 3 meet": [arm.wrist(), arm.meet(2, 3)],
    }  # fmt: skip
    return "; ".join(c for c in checks[description] if c)


def geometry(chain: Chain) -> Geometry:
    """The closed-form split of ``chain``'s inverse kinematics (found once per chain).

    Raises:
        AnalyticIKError: not six revolute joints, or no supported geometry within
            :data:`GEOMETRY_TOL`; the message names each condition that fails, by how much.
    """
    found = _GEOMETRIES.get(chain)
    if found is None:
        found = _find(chain)
        _GEOMETRIES[chain] = found
    return found


def _find(chain: Chain, tol: float = GEOMETRY_TOL) -> Geometry:
    """The split of the first supported geometry ``chain`` has within ``tol``."""
    name = chain.robot or "this chain"
    if chain.n_joints != 6 or any(t != "revolute" for t in chain.joint_types):
        kinds = "".join("R" if t == "revolute" else "P" for t in chain.joint_types)
        raise AnalyticIKError(
            f"ik_all needs 6 revolute joints; {name} has {chain.n_joints} ({kinds}): "
            "use the numerical chain.ik"
        )
    arm = _Arm(chain, tol)
    three = arm.parallel(2, 3) or arm.parallel(2, 4) or arm.meet(5, 6) or arm.crossing(2, 5)
    if not three:
        return _three_parallel_geometry(arm)
    tried = [("three parallel axes (2, 3, 4) with axes 5 and 6 meeting", three)]
    wrist = arm.wrist()
    if wrist:
        tried.append(("a spherical wrist (axes 4, 5, 6 meeting)", wrist))
        raise AnalyticIKError(_describe_failure(chain, arm, tried))
    shoulders = [
        ("axes 2 and 3 parallel", arm.parallel(2, 3) or arm.crossing(1, 2), _TwoParallel),
        ("axes 1 and 2 meet", arm.meet(1, 2), _OneTwoMeet),
        ("axes 2 and 3 meet", arm.meet(2, 3), _TwoThreeMeet),
    ]
    for what, fails, split in shoulders:
        if not fails:
            return _spherical_geometry(arm, what, split)
    why = ", ".join(fails for _, fails, _ in shoulders)
    tried.append(("a spherical wrist (axes 4, 5, 6 meet) with its first three axes", why))
    raise AnalyticIKError(_describe_failure(chain, arm, tried))


# --- the constants of a split ------------------------------------------------------------------


def _v(x: ArrayLike) -> Vec:
    a = np.asarray(x, dtype=np.float64)
    return (float(a[0]), float(a[1]), float(a[2]))


def _unit_normal(w: FloatArray, hint: FloatArray) -> FloatArray:
    """The unit vector normal to ``w`` nearest ``hint`` (not along ``w``)."""
    n = hint - w * (hint @ w)
    return np.asarray(n / np.linalg.norm(n), dtype=np.float64)


@dataclasses.dataclass(frozen=True)
class _Wrist:
    """Constants of the last three joints' rotations: axes, and the two directions followed
    through them (``h6`` and a normal ``x6`` of it) in the end frame (``M``'s rotation^T)."""

    h: tuple[Vec, ...]  # the six axes
    minus: tuple[Vec, ...]  # their opposites: rot(-h, q) = rot(h, q)^T
    h6_end: Vec
    x6: Vec
    x6_end: Vec
    d56: float  # h5 . h6
    tol: float  # subproblem tolerances for directions (_EXISTS, _DEGENERATE)
    tiny: float


def _wrist_constants(arm: _Arm) -> _Wrist:
    h = [line.w for line in arm.lines]
    R_M = arm.home[:3, :3]
    x6 = _unit_normal(h[5], h[4])  # axes 5 and 6 meet, so they are not parallel
    return _Wrist(
        h=tuple(_v(w) for w in h),
        minus=tuple(_v(-w) for w in h),
        h6_end=_v(R_M.T @ h[5]),
        x6=_v(x6),
        x6_end=_v(R_M.T @ x6),
        d56=float(h[4] @ h[5]),
        tol=_EXISTS,
        tiny=_DEGENERATE,
    )


def _flat(consts: Any) -> FloatArray:
    """A split's constants in declaration order (nested dataclasses and vectors flattened):
    the compiled kernel reads them as a struct of doubles in the same order."""
    out: list[float] = []
    for field in dataclasses.fields(consts):
        value = getattr(consts, field.name)
        if dataclasses.is_dataclass(value):
            out.extend(_flat(value))
        else:
            out.extend(np.ravel(value).tolist())
    flat = np.array(out, dtype=np.float64)
    flat.flags.writeable = False
    return flat


def _in_end_frame(arm: _Arm, x: FloatArray) -> Vec:
    """A point at ``q = 0`` in end-frame coordinates: ``M^-1 x``."""
    return _v(arm.home[:3, :3].T @ (x - arm.home[:3, 3]))


class _Branches(NamedTuple):
    """Each joint's angle as cosine and sine (broadcastable to the branch shape) and whether
    the branch exists."""

    angles: tuple[CosSin, ...]
    exists: Any


class _Target(NamedTuple):
    R: _pose.Mat  # the target's rotation, entries (N,)
    p: _pose.Vec  # its position


# --- three parallel axes -----------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _ThreeParallel:
    wrist: _Wrist
    h: Vec  # axis 2's direction, shared by 3 and 4 (as their sense allows)
    minus_h: Vec
    h3: Vec  # axis 3's direction, sign3 h
    sign3: float  # +-1
    sign4: float
    r1: Vec
    r2: Vec
    c56_end: Vec  # where axes 5 and 6 meet, in the end frame
    d1: float  # h . (c56 - r1)
    c56_r4: Vec  # c56 - r4
    p32: Vec  # r3 - r2
    p43: Vec  # r4 - r3
    p23: Vec  # r2 - r3
    tol: float  # subproblem tolerances in lengths (m) and lengths squared
    tiny: float
    tol2: float
    tiny2: float


def _three_parallel_geometry(arm: _Arm) -> Geometry:
    l1, l2, l3, l4 = (arm.line(i) for i in (1, 2, 3, 4))
    h = l2.w
    r2 = _foot(l1.point, l2)
    r3, r4 = _foot(r2, l3), _foot(r2, l4)  # r3 - r2 and r4 - r3 normal to h
    c56 = _meet(arm.line(5), arm.line(6))
    consts = _ThreeParallel(
        wrist=_wrist_constants(arm),
        h=_v(h),
        minus_h=_v(-h),
        h3=_v(np.sign(l3.w @ h) * h),
        sign3=float(np.sign(l3.w @ h)),
        sign4=float(np.sign(l4.w @ h)),
        r1=_v(l1.point),
        r2=_v(r2),
        c56_end=_in_end_frame(arm, c56),
        d1=float(h @ (c56 - l1.point)),
        c56_r4=_v(c56 - r4),
        p32=_v(r3 - r2),
        p43=_v(r4 - r3),
        p23=_v(r2 - r3),
        tol=_EXISTS * arm.size,
        tiny=_DEGENERATE * arm.size,
        tol2=_EXISTS * arm.size**2,
        tiny2=_DEGENERATE * arm.size**2,
    )
    description = "three parallel axes (2, 3, 4), axes 5 and 6 meet"
    return _geometry("three parallel axes", description, arm, consts, _solve_three_parallel)


def _geometry(
    kind: str, description: str, arm: _Arm, consts: Any, solve: Callable[[Any, _Target], _Branches]
) -> Geometry:
    split = type(consts.shoulder) if isinstance(consts, _Spherical) else type(consts)
    return Geometry(
        kind, description, arm.size, 8, functools.partial(solve, consts), _KINDS[split],
        _flat(consts),
    )  # fmt: skip


class _WristTurns(NamedTuple):
    """The last three rotations of one branch axis (:func:`_wrist`)."""

    turn: sp.Quadratic  # the first rotation's subproblem: roots, exists, degenerate
    first: CosSin  # its roots (a new last axis)
    a5: CosSin
    a6: CosSin
    sign: Any  # +-1: axis 6 turned by q5 points along (or against) the first axis
    phi: CosSin  # first + sign q6: what the first and the last share at a singularity


def _wrist(W: _Wrist, axis: Vec, minus_axis: Vec, v: _pose.Vec, x: _pose.Vec) -> _WristTurns:
    """The first rotation (about ``axis``: joint 4, or joints 2 to 4 of three parallel axes), q5
    and q6 that turn axis 6 and its normal ``x6`` into ``v`` and ``x`` (both turned back through
    the joints before): the first rotation and q5 by subproblem 4 on the circle of ``v`` about
    ``axis`` (it shrinks to a point at the wrist singularity) then 1, q6 by subproblem 1."""
    turn = sp.sp4_cs(W.h[4], v, minus_axis, W.d56, W.tol, W.tiny)
    first = turn.root
    u = rotate(minus_axis, first, lift(v))  # = rot(h5, q5) h6
    a5 = sp.sp1_cs(W.h[5], u, W.h[4])
    x = rotate(W.minus[4], a5, rotate(minus_axis, first, lift(x)))
    a6 = sp.sp1_cs(W.x6, x, W.h[5])
    sign = np.where(dot(axis, u) < 0.0, -1.0, 1.0)
    return _WristTurns(turn, first, a5, a6, sign, _plus(first, a6, sign))


def _solve_three_parallel(P: _ThreeParallel, target: _Target) -> _Branches:
    """Branch axes: q1 (2), then q2 + q3 + q4 with q5 (2), then the elbow (2)."""
    W = P.wrist
    minus_h1, h3 = W.minus[0], P.h3
    R, p = target
    # q1: the point where axes 5 and 6 meet keeps its height along h through joints 2 to 6
    y1 = sub(add(_pose.mat_vec(R, P.c56_end), p), P.r1)
    shoulder = sp.sp4_cs(P.h, y1, minus_h1, P.d1, P.tol, P.tiny)  # (N, 2)
    a1 = shoulder.root
    # theta = q2 + q3 + q4 (as turns about h) and q5: axis 6 points along
    # v = rot(h, theta) rot(h5, q5) h6 in joint 1's frame
    v = rotate(minus_h1, a1, lift(_pose.mat_vec(R, W.h6_end)))
    x = rotate(minus_h1, a1, lift(_pose.mat_vec(R, W.x6_end)))
    turn, theta, a5, a6, sign, phi = _wrist(W, P.h, P.minus_h, v, x)  # (N, 2, 2)
    # the planar arm: joints 2 and 3 put axis 4's point r4 at z, theta turns the rest about it
    back = add(rotate(minus_h1, a1, lift(y1)), P.r1)  # e1^-1 y
    # wrist singularity (axis 6 along h): theta and q6 turn about parallel axes and only
    # phi = theta + sign q6 is fixed. The roots become the two turns theta that put where
    # axes 5 and 6 meet in line with axis 2 and axis 4's point r4 (nearest and furthest
    # from axis 2: one is within reach if any theta is), and q6 = sign (phi - theta).
    fold = sp.sp1_cs(P.c56_r4, sub(back, P.r2), P.h)
    ends = CosSin(fold.c[..., None] * _ENDS, fold.s[..., None] * _ENDS)
    singular = turn.degenerate[..., None]
    theta = _pick(singular, ends, theta)
    rest = _minus(phi, theta)
    a6 = _pick(singular, CosSin(rest.c, sign * rest.s), a6)
    zr = sub(sub(lift(back), rotate(P.h, theta, P.c56_r4)), P.r2)  # e2 e3 r4 - r2
    elbow = sp.sp3_cs(P.p43, P.p23, h3, dot(zr, zr), P.tol2, P.tiny2)  # (N, 2, 2, 2)
    a3 = elbow.root
    a2 = sp.sp1_cs(add(P.p32, rotate(h3, a3, P.p43)), lift(zr), P.h)
    # q4 = sign4 (theta - q2 - sign3 q3)
    c23 = a2.c * a3.c - P.sign3 * (a2.s * a3.s)
    s23 = a2.s * a3.c + P.sign3 * (a2.c * a3.s)
    tc, ts = theta.c[..., None], theta.s[..., None]
    a4 = CosSin(tc * c23 + ts * s23, P.sign4 * (ts * c23 - tc * s23))
    exists = (
        shoulder.exists[..., None, None, None]
        & turn.exists[..., None, None]
        & elbow.exists[..., None]
    )
    return _Branches((_up(a1, 2), a2, a3, a4, _up(a5, 1), _up(a6, 1)), exists)


def _up(a: CosSin, n: int) -> CosSin:
    """``a`` with ``n`` new last axes (branches it does not depend on)."""
    index = (..., *([None] * n))
    return CosSin(a.c[index], a.s[index])


def _plus(a: CosSin, b: CosSin, sign: Any) -> CosSin:
    """The angle ``a + sign b`` (``sign`` = +-1)."""
    return CosSin(a.c * b.c - sign * (a.s * b.s), a.s * b.c + sign * (a.c * b.s))


def _minus(a: CosSin, b: CosSin) -> CosSin:
    """The angle ``a - b``."""
    return CosSin(a.c * b.c + a.s * b.s, a.s * b.c - a.c * b.s)


def _half(a: CosSin) -> CosSin:
    """The angle ``a / 2`` for ``a`` in ``(-pi, pi]``: ``(1 + c, s)`` normalised where
    ``c >= 0``, else ``(s, 1 - c)`` with the sign of ``s`` (both are ``2 cos(a/2)`` or
    ``2 sin(a/2)`` times the half angle's cosine and sine)."""
    flip = np.where(a.s < 0.0, -1.0, 1.0)
    front = a.c >= 0.0
    x = np.where(front, 1.0 + a.c, flip * a.s)
    y = np.where(front, a.s, flip * (1.0 - a.c))
    return sp.unit(x, y)


def _pick(where: Any, yes: CosSin, no: CosSin) -> CosSin:
    return CosSin(np.where(where, yes.c, no.c), np.where(where, yes.s, no.s))


# --- spherical wrist ---------------------------------------------------------------------------


class _Shoulder(NamedTuple):
    """The first three joints' angles (broadcastable to ``(N, 2, 2)``) and their existence."""

    angles: tuple[CosSin, CosSin, CosSin]
    exists: Any


@dataclasses.dataclass(frozen=True)
class _Spherical:
    wrist: _Wrist
    pw_end: Vec  # the wrist centre in the end frame
    shoulder: _ShoulderSplit  # the wrist centre's target position -> q1, q2, q3


def _spherical_geometry(arm: _Arm, what: str, split: type[_ShoulderSplit]) -> Geometry:
    pw = _meet(arm.line(4), arm.line(5))
    consts = _Spherical(_wrist_constants(arm), _in_end_frame(arm, pw), split.of(arm, pw))
    description = f"spherical wrist (axes 4, 5, 6 meet), {what}"
    return _geometry("spherical wrist", description, arm, consts, _solve_spherical)


def _solve_spherical(P: _Spherical, target: _Target) -> _Branches:
    """Branch axes: the first three joints' two (q1 or q3, then the other), then the wrist's."""
    W = P.wrist
    R, p = target
    first = P.shoulder(add(_pose.mat_vec(R, P.pw_end), p))
    a1, a2, a3 = first.angles
    # axis 6's direction and its normal in joint 3's frame: the wrist's rotation R4 R5 R6
    # applied to h6 and x6
    v = _back(W, (a1, a2, a3), _pose.mat_vec(R, W.h6_end))  # (N, 2, 2)
    x = _back(W, (a1, a2, a3), _pose.mat_vec(R, W.x6_end))
    turn, a4, a5, a6, sign, phi = _wrist(W, W.h[3], W.minus[3], v, x)  # (N, 2, 2, 2)
    # wrist singularity (axes 4 and 6 aligned): only phi = q4 + sign q6 is fixed, phi in
    # (-pi, pi]. The two roots become phi shared evenly (q4 = sign q6 = phi / 2, each within
    # +-pi/2) and phi all on q6 (q4 = 0)
    half = _half(phi)
    even = _EVEN  # the + root: shared evenly; the - root: q4 = 0
    singular = turn.degenerate[..., None]
    a4 = _pick(singular, CosSin(np.where(even, half.c, 1.0), np.where(even, half.s, 0.0)), a4)
    on6 = CosSin(np.where(even, half.c, phi.c), np.where(even, half.s, phi.s))
    a6 = _pick(singular, CosSin(on6.c, sign * on6.s), a6)
    exists = first.exists[..., None] & turn.exists[..., None]
    return _Branches((_up(a1, 1), _up(a2, 1), _up(a3, 1), a4, a5, a6), exists)


def _back(W: _Wrist, shoulder: tuple[CosSin, CosSin, CosSin], x: _pose.Vec) -> _pose.Vec:
    """``(R1 R2 R3)^T x`` for ``(N,)`` entries ``x``: entries of shape ``(N, 2, 2)``."""
    out: _pose.Vec = (x[0][:, None, None], x[1][:, None, None], x[2][:, None, None])
    for axis, a in zip(W.minus[:3], shoulder, strict=True):
        out = rotate(axis, a, out)
    return out


def _scales(arm: _Arm) -> dict[str, float]:
    """Subproblem tolerances: existence and point circle, in metres and in metres squared."""
    L = arm.size
    return {"tol": _EXISTS * L, "tiny": _DEGENERATE * L, "tol2": _EXISTS * L * L,
            "tiny2": _DEGENERATE * L * L}  # fmt: skip


@dataclasses.dataclass(frozen=True)
class _TwoParallel:
    """Axes 2 and 3 parallel: q1 keeps the wrist centre's height along them (subproblem 4),
    the elbow q3 its distance from axis 2 (subproblem 3), then q2 (subproblem 1)."""

    h2: Vec
    h3: Vec
    minus_h1: Vec
    r1: Vec
    r2: Vec
    pw3: Vec  # pw - r3
    p23: Vec  # r2 - r3
    p32: Vec
    d1: float  # h2 . (pw - r1)
    tol: float
    tiny: float
    tol2: float
    tiny2: float

    @classmethod
    def of(cls, arm: _Arm, pw: FloatArray) -> _TwoParallel:
        l1, l2, l3 = arm.line(1), arm.line(2), arm.line(3)
        r2 = _foot(l1.point, l2)
        r3 = _foot(r2, l3)
        return cls(
            _v(l2.w), _v(l3.w), _v(-l1.w), _v(l1.point), _v(r2), _v(pw - r3), _v(r2 - r3),
            _v(r3 - r2), float(l2.w @ (pw - l1.point)), **_scales(arm),
        )  # fmt: skip

    def __call__(self, y: Vec) -> _Shoulder:
        y1 = sub(y, self.r1)
        shoulder = sp.sp4_cs(self.h2, y1, self.minus_h1, self.d1, self.tol, self.tiny)  # q1
        zr = sub(add(rotate(self.minus_h1, shoulder.root, lift(y1)), self.r1), self.r2)
        elbow = sp.sp3_cs(self.pw3, self.p23, self.h3, dot(zr, zr), self.tol2, self.tiny2)  # q3
        a2 = sp.sp1_cs(add(self.p32, rotate(self.h3, elbow.root, self.pw3)), lift(zr), self.h2)
        exists = shoulder.exists[..., None, None] & elbow.exists[..., None]
        return _Shoulder((_up(shoulder.root, 1), a2, elbow.root), exists)


@dataclasses.dataclass(frozen=True)
class _OneTwoMeet:
    """Axes 1 and 2 meet at c: q3 keeps the wrist centre's distance from c (subproblem 3),
    then q1 and q2 turn it into place (subproblem 2, the circle about axis 1 first)."""

    h2: Vec
    h3: Vec
    minus_h1: Vec
    c: Vec
    pw3: Vec  # pw - r3
    pc3: Vec  # c - r3
    p3c: Vec
    tol: float
    tiny: float
    tol2: float
    tiny2: float

    @classmethod
    def of(cls, arm: _Arm, pw: FloatArray) -> _OneTwoMeet:
        l1, l2, l3 = arm.line(1), arm.line(2), arm.line(3)
        c = _meet(l1, l2)
        return cls(
            _v(l2.w), _v(l3.w), _v(-l1.w), _v(c), _v(pw - l3.point), _v(c - l3.point),
            _v(l3.point - c), **_scales(arm),
        )  # fmt: skip

    def __call__(self, y: Vec) -> _Shoulder:
        yc = sub(y, self.c)
        elbow = sp.sp3_cs(self.pw3, self.pc3, self.h3, dot(yc, yc), self.tol2, self.tiny2)  # q3
        xc = add(self.p3c, rotate(self.h3, elbow.root, self.pw3))  # e3 pw - c
        yc1 = lift(yc)
        shoulder = sp.sp4_cs(self.h2, yc1, self.minus_h1, dot(self.h2, xc), self.tol, self.tiny)
        a2 = sp.sp1_cs(lift(xc), rotate(self.minus_h1, shoulder.root, lift(yc1)), self.h2)
        exists = elbow.exists[..., None, None] & shoulder.exists[..., None]
        return _Shoulder((shoulder.root, a2, _up(elbow.root, 1)), exists)


@dataclasses.dataclass(frozen=True)
class _TwoThreeMeet:
    """Axes 2 and 3 meet at c: q1 keeps the wrist centre's distance from c (subproblem 3),
    then q2 and q3 turn it into place (subproblem 2, the circle about axis 2 first)."""

    h3: Vec
    minus_h1: Vec
    minus_h2: Vec
    r1: Vec
    pc1: Vec  # c - r1
    pwc: Vec  # pw - c
    c: Vec
    dist2: float  # |pw - c|^2
    d3: float  # h3 . (pw - c)
    tol: float
    tiny: float
    tol2: float
    tiny2: float

    @classmethod
    def of(cls, arm: _Arm, pw: FloatArray) -> _TwoThreeMeet:
        l1, l2, l3 = arm.line(1), arm.line(2), arm.line(3)
        c = _meet(l2, l3)
        return cls(
            _v(l3.w), _v(-l1.w), _v(-l2.w), _v(l1.point), _v(c - l1.point), _v(pw - c), _v(c),
            float((pw - c) @ (pw - c)), float(l3.w @ (pw - c)), **_scales(arm),
        )  # fmt: skip

    def __call__(self, y: Vec) -> _Shoulder:
        y1 = sub(y, self.r1)
        shoulder = sp.sp3_cs(y1, self.pc1, self.minus_h1, self.dist2, self.tol2, self.tiny2)
        zc = sub(add(rotate(self.minus_h1, shoulder.root, lift(y1)), self.r1), self.c)
        upper = sp.sp4_cs(self.h3, zc, self.minus_h2, self.d3, self.tol, self.tiny)  # q2
        a3 = sp.sp1_cs(self.pwc, rotate(self.minus_h2, upper.root, lift(zc)), self.h3)
        exists = shoulder.exists[..., None, None] & upper.exists[..., None]
        return _Shoulder((_up(shoulder.root, 1), upper.root, a3), exists)


_ShoulderSplit = _TwoParallel | _OneTwoMeet | _TwoThreeMeet
# the compiled kernel's number for each split (_kernel.c: IK_*)
_KINDS: dict[type, int] = {_ThreeParallel: 0, _TwoParallel: 1, _OneTwoMeet: 2, _TwoThreeMeet: 3}


# --- solving -----------------------------------------------------------------------------------


def _as_poses(T: ArrayLike) -> FloatArray:
    """``T`` as a float64 array of shape ``(..., 4, 4)``, or :class:`InputError`."""
    arr = real_array(T, "target poses")
    if arr.ndim < 2 or arr.shape[-2:] != (4, 4):
        raise InputError(f"target poses must have shape (..., 4, 4), got {arr.shape}")
    return arr


def _targets(T: ArrayLike) -> FloatArray:
    """``T`` as float64 ``(..., 4, 4)`` rigid transforms, or :class:`InputError`."""
    arr = _as_poses(T)
    if not np.all(np.isfinite(arr)):
        raise InputError("target poses contain NaN or inf; every entry must be finite")
    R = arr[..., :3, :3]
    gram = np.einsum("...ji,...jk->...ik", R, R)
    bad = np.any(np.abs(gram - np.eye(3)) > _RIGID_TOL, axis=(-2, -1)) | (np.linalg.det(R) < 0)
    bad |= np.any(arr[..., 3, :] != np.array([0.0, 0.0, 0.0, 1.0]), axis=-1)
    if np.any(bad):
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise InputError(
            f"target pose {where} is not a rigid transform: the rotation block must be "
            f"orthonormal with det +1 (to {_RIGID_TOL:g}) and the last row [0, 0, 0, 1]"
        )
    return arr


def ik_all(
    chain: Chain, T: ArrayLike, *, near: ArrayLike | None = None, refine: bool = True
) -> IKSolutions:
    """Every closed-form solution of ``chain.fk(q) = T`` (:meth:`poekin.Chain.ik_all`).

    Runs in the compiled kernel where it is installed (:func:`solve_kernel`), else on the
    NumPy reference path (:func:`solve_numpy`); both give the same solutions. A chain within
    :data:`NEAR_TOL` of a supported geometry but not on it (a calibrated arm) is solved in the
    nearest ideal geometry's closed form, and each branch refined on the chain by the
    numerical solver from there (``chain.ik`` with that start, one attempt): ``valid`` then
    means it converged to the default tolerances (1e-10 m and rad), within the limits, and is
    not the solution of an earlier branch (:attr:`Geometry.nearest` says how near the chain is).

    Args:
        chain: six revolute joints in a supported geometry, or near one (:func:`geometry`,
            :func:`nearest_geometry`).
        T: ``(..., 4, 4)`` target poses ``T_world_frame`` of the chain's end frame.
        near: ``(..., 6)`` joint values (the robot's current ones): each branch's angles are
            given as their equivalents nearest them (:func:`poekin.wrap`), and the branches
            are ordered by their distance to them, the valid ones first. None: the geometry's
            own order.
        refine: allow the refinement of a near geometry (the default); False solves only a
            chain that has its geometry exactly, and raises for one near it.

    Returns:
        :class:`IKSolutions` with ``q`` ``(..., k, 6)`` and ``valid`` ``(..., k)``.

    Raises:
        AnalyticIKError: the chain has no closed form here (:func:`geometry`).
        InputError: ``T`` is not ``(..., 4, 4)`` finite rigid transforms, or ``near`` not
            joint values that broadcast against them.
    """
    if refine is True and _kernel is not None and type(T) is np.ndarray:
        quick = _quick(chain, T, near)  # the exact geometry's kernel, with the least around it
        if quick is not None:
            return quick
    if not isinstance(refine, bool):
        raise InputError(f"refine must be True or False, got {refine!r}")
    geo = nearest_geometry(chain) if refine else geometry(chain)
    arr = _as_poses(T)
    batch = arr.shape[:-2]
    k = geo.n_solutions
    found = _solve_kernel(geo, chain, arr)
    if found is None:
        q, valid = _solve_numpy(geo, chain, _targets(arr).reshape(-1, 4, 4))
    else:
        q, valid = found
    if geo.nearest:
        q, valid = _refined(chain, arr.reshape(-1, 4, 4), q, valid)
    q, valid = q.reshape(*batch, k, 6), valid.reshape(*batch, k)
    if near is not None:
        q, valid = _ordered(chain, q, valid, near)
    return IKSolutions(q, valid, geo, chain, arr)


def _quick(chain: Chain, T: FloatArray, near: ArrayLike | None) -> IKSolutions | None:
    """:func:`ik_all` of a NumPy array ``T`` on a chain of a supported geometry (not a near
    one), as the usual path solves it (and orders it, with ``near``), with less around the
    kernel; None where that does not serve (the geometry not yet found or only near, ``T`` not
    a plain float64 ``(..., 4, 4)`` array, a target that is not a rigid transform): the usual
    path then says what is wrong."""
    global _last
    ref, geo = _last  # one read: another thread may set it meanwhile
    if ref() is not chain:  # not a control loop's chain, as last time
        geo = _NEAREST.get(chain)
        if type(geo) is not Geometry or geo.nearest:
            return None
        _last = weakref.ref(chain), geo
        # Chain.ik_all(T)'s own call in C from now on (fast_method)
        armed = (_kernel.quick_ik_all, geo._kind, geo._params, chain.limits, geo, IKSolutions)
        object.__setattr__(chain, "_ik_all_quick", armed)
    done = _kernel.ik_all(geo._kind, geo._params, T, chain.limits, True)  # in T's batch shape
    if done is None:
        return None
    q, valid, _ = done
    if near is not None:
        q, valid = _ordered(chain, q, valid, near)
    found = _new(IKSolutions)
    d = found.__dict__  # as the dataclass's __init__ sets them, without its five calls
    d["q"], d["valid"], d["geometry"], d["_chain"], d["_targets"] = q, valid, geo, chain, T
    return found


_new = object.__new__


def _nobody() -> None:
    return None


# the chain :func:`_quick` last solved (weakly) and its exact geometry
_last: tuple[Callable[[], Chain | None], Any] = (_nobody, None)


def nearest_branch(
    chain: Chain, T: ArrayLike, q0: ArrayLike, numerical: Callable[[], IKResult]
) -> IKResult:
    """:meth:`poekin.Chain.ik` with ``nearest_branch``: each target's valid closed-form
    branch nearest ``q0`` (as :func:`ik_all` with ``near``), and where a target has none,
    the numerical solve's answer (``numerical()``, run only then, on every target)."""
    from poekin.ik.numerical import IKResult

    found = ik_all(chain, T, near=q0)
    best_q, best = found.q[..., 0, :], found.valid[..., 0]
    pos, ori = found.pos_err[..., 0], found.ori_err[..., 0]
    zero, one = np.zeros(best.shape, dtype=np.int64), np.ones(best.shape, dtype=np.int64)
    if np.all(best):
        return IKResult(best_q, best, pos, ori, zero, one)
    other = numerical()
    pick = best[..., None]
    return IKResult(
        np.where(pick, best_q, other.q),
        np.where(best, True, other.success),
        np.where(best, pos, other.pos_err),
        np.where(best, ori, other.ori_err),
        np.where(best, zero, other.iterations),
        np.where(best, one, other.attempts),
    )


# Two refined branches this close (rad, every joint) reached the same solution: near a fold,
# where the Jacobian's smallest singular value is 1e-4, a solve to 1e-10 m and rad leaves q
# uncertain by some 1e-6, and two solutions of a pair that close are one to any controller
_SAME = 1e-5


# A lost branch starts again these far (rad) on either side of its start, in turn, along the
# direction in which two solutions meeting at a fold of the arm part (near a straight wrist,
# along which the wrist's turns trade, the calibrated arm's solution can be a radian away)
_FOLD_STEPS = (0.05, 0.3, 1.0)


# A branch whose middle wrist joint is this near a straight wrist (|sin q5|: axes 4 and 6
# nearly parallel) may have a second solution near it, or one where the ideal geometry has none
_STRAIGHT_WRIST = 0.05
# ... and its twin is looked for this far (rad) either side of it, along the direction in which
# the two part (the largest of :data:`_FOLD_STEPS`: the twins found in bench_ik.py's calibrated
# UR5e were a radian apart; the smaller steps found none the largest did not)
_TWIN_STEP = 1.0


# The refinement's tolerances (m, rad): a hundredth of the solver's default, so that a solution
# near a fold (the Jacobian's smallest singular value 1e-4) comes back within some 1e-8 rad
# of the exact one, not 1e-6; a branch is valid where it meets the default (1e-10)
_TIGHT = 1e-12
_VALID = 1e-10


@functools.cache
def _refine_settings() -> Any:
    """The refinement's numerical settings: one attempt to :data:`_TIGHT`."""
    from poekin.ik import numerical

    return numerical.settings(max_attempts=1, pos_tol=_TIGHT, ori_tol=_TIGHT)


def _refined(
    chain: Chain, T: FloatArray, q: FloatArray, exists: BoolArray
) -> tuple[FloatArray, BoolArray]:
    """Each branch of ``q`` ``(n, k, 6)`` (the nearest ideal geometry's, for targets ``T``
    ``(n, 4, 4)``; ``exists`` ``(n, k)`` where that geometry reaches the target) refined on
    ``chain``: ``q`` and ``valid`` (converged, within the limits, and not a solution an
    earlier branch of its target reached).

    Near a fold of the arm (a stretched or folded elbow, the wrist centre near axis 1, a
    straight wrist) two solutions of the chain are close, and the ideal geometry may give both
    one start (its two roots merge there) or none. A branch that reached its twin's solution,
    or did not converge, starts again: from its start mirrored through the solution its twin
    reached (the other side of the fold), then steps of :data:`_FOLD_STEPS` either side of its
    start along the right singular vector of the Jacobian's smallest singular value there (the
    direction in which the two solutions part); it is kept if it reaches a solution of its
    own. Near a straight wrist the chain can have two solutions near one of the ideal
    geometry's: :func:`_twins` puts the second in a branch that has none. Every solve goes to
    :data:`_TIGHT`, so that a solution near a fold is the exact one to some 1e-8 rad."""
    limits = chain.limits
    assert limits is not None  # Chain.__post_init__ sets them
    lo, hi = limits[:, 0], limits[:, 1]
    # inside the limits (the solver says nothing of it), and finite: a branch the ideal
    # geometry could not compute (NaN, for a target beyond float64's range of squares) starts
    # at 0 brought into them
    start = np.clip(np.where(np.isfinite(q), q, 0.0), lo, hi)
    n, k = q.shape[:2]
    targets = np.repeat(T, k, axis=0).reshape(n, k, 4, 4)  # contiguous: the kernel's own
    out, met = _solve(chain, targets, start, clipped=True)  # within the limits, near the start: the
    # closed form's convention
    valid = _distinct(out, met)
    # lost where a solution may be: a twin (two roots that merged in the ideal geometry reach
    # one solution), or a branch the ideal geometry reaches; one it does not reach, and that
    # did not converge, has none
    lost = (met & ~valid) | (exists & ~met)
    # near a straight wrist, a solution the ideal geometry does not reach may be there
    lost |= ~met & (np.abs(np.sin(start[..., 4])) < _STRAIGHT_WRIST)
    t, b = np.nonzero(lost)
    if not len(t):
        return out, valid
    s0 = start[t, b]
    mirrored = 2.0 * s0 - out[t, b]  # the other side of the fold from where it ended
    _retry(chain, targets[t, b], mirrored, t, b, out, valid)
    left = ~valid[t, b]
    if left.any():  # steps either side along the direction in which the two solutions part
        t, b, s0 = t[left], b[left], s0[left]
        fold = _parting(chain, s0)
        for step in _FOLD_STEPS:
            for side in (step, -step):
                _retry(chain, targets[t, b], s0 + side * fold, t, b, out, valid)
            left = ~valid[t, b]
            t, b, s0, fold = t[left], b[left], s0[left], fold[left]
            if not len(t):
                break
    _twins(chain, targets, out, valid)
    return out, valid


def _twins(chain: Chain, targets: FloatArray, out: FloatArray, valid: BoolArray) -> None:
    """Near a straight wrist the chain can have two solutions where the ideal geometry has
    one (up to 16 in all, a general arm's most): from each valid solution there whose target
    has a branch without one, a step of :data:`_TWIN_STEP` either side along the direction in
    which the two part; a solution apart from every valid one of its target takes that free
    branch (``out`` and ``valid`` in place)."""
    near = valid & (np.abs(np.sin(out[..., 4])) < _STRAIGHT_WRIST)
    t, b = np.nonzero(near & ~np.all(valid, axis=-1, keepdims=True))
    if not len(t):
        return
    s0 = out[t, b]
    fold = _parting(chain, s0)
    for side in (_TWIN_STEP, -_TWIN_STEP):
        q, met = _solve(chain, targets[t, b], s0 + side * fold)
        gap = np.max(np.abs(out[t] - q[:, None, :]), axis=-1)  # (rows, k)
        for row in np.flatnonzero(met & ~np.any(valid[t] & (gap < _SAME), axis=-1)):
            i = t[row]  # one at a time: two rows of a target may find one solution
            free = np.flatnonzero(~valid[i])
            if len(free) and not np.any(valid[i] & (np.max(np.abs(out[i] - q[row]), -1) < _SAME)):
                out[i, free[0]], valid[i, free[0]] = q[row], True


def _parting(chain: Chain, q: FloatArray) -> FloatArray:
    """``(m, 6)`` unit vectors at ``q (m, 6)``: the right singular vector of the space
    Jacobian's smallest singular value, the direction in which two solutions near a fold
    part (the eigenvector of ``J^T J``'s smallest eigenvalue: half an SVD's time; either
    sign, and the direction to 1e-14 where the two smallest singular values are 0.01 apart)."""
    J = chain.jacobian_space(q)
    parting: FloatArray = np.linalg.eigh(np.swapaxes(J, -1, -2) @ J)[1][..., 0]
    return parting


def _solve(
    chain: Chain, T: FloatArray, q0: FloatArray, *, clipped: bool = False
) -> tuple[FloatArray, BoolArray]:
    """The refinement's solve of ``T`` ``(..., 4, 4)`` (C-contiguous rigid transforms, which
    :func:`ik_all` has checked) from finite ``q0`` ``(..., 6)`` (brought into the limits
    unless ``clipped`` says it is: the solver says nothing of it), one attempt to
    :data:`_TIGHT`: ``q`` and where it meets the default tolerances (:data:`_VALID`)."""
    from poekin.ik import numerical

    limits = chain.limits
    assert limits is not None
    start = q0 if clipped else np.clip(q0, limits[:, 0], limits[:, 1])
    found = numerical.solve_valid(chain, T, start, _refine_settings())
    met: BoolArray = (found.pos_err <= _VALID) & (found.ori_err <= _VALID)
    return found.q, met


def _retry(
    chain: Chain,
    T: FloatArray,
    q0: FloatArray,
    t: NDArray[np.intp],
    b: NDArray[np.intp],
    out: FloatArray,
    valid: BoolArray,
) -> None:
    """Branches ``b`` of targets ``t`` solved again from ``q0`` (``(m, 6)``, for targets
    ``T`` ``(m, 4, 4)``): where one converges to a solution apart from every valid one of its
    target, ``out`` and ``valid`` take it (one branch index at a time: two lost branches may
    find the same solution)."""
    q, met = _solve(chain, T, q0)
    for branch in np.unique(b):
        rows = np.flatnonzero(met & (b == branch) & ~valid[t, b])
        if not len(rows):
            continue
        gap = np.max(np.abs(out[t[rows]] - q[rows, None, :]), axis=-1)  # (rows, k)
        new = rows[~np.any(valid[t[rows]] & (gap < _SAME), axis=-1)]
        out[t[new], branch], valid[t[new], branch] = q[new], True


# k -> the k (k - 1) / 2 pairs of branches (b, a), a < b
_PAIRS: dict[int, tuple[NDArray[np.intp], NDArray[np.intp]]] = {}


def _distinct(q: FloatArray, ok: BoolArray) -> BoolArray:
    """``ok`` ``(n, k)`` less each branch whose solution an earlier one of its target
    reached: the pairs whose first joints agree (few: the two shoulders differ), then all."""
    k = q.shape[1]
    if k not in _PAIRS:
        later, first_of = np.nonzero(np.tri(k, k, -1, dtype=np.bool_))
        _PAIRS[k] = later, first_of
    later, first_of = _PAIRS[k]
    first = q[:, :, 0]
    close = np.abs(first[:, later] - first[:, first_of]) < _SAME  # (n, pairs)
    t, p = np.nonzero(close & ok[:, later] & ok[:, first_of])
    b, a = later[p], first_of[p]
    twin = np.max(np.abs(q[t, b] - q[t, a]), axis=-1) < _SAME
    valid: BoolArray = ok.copy()
    valid[t[twin], b[twin]] = False
    return valid


def _ordered(
    chain: Chain, q: FloatArray, valid: BoolArray, near: ArrayLike
) -> tuple[FloatArray, BoolArray]:
    """``q`` ``(..., k, 6)`` as the equivalents nearest ``near``, the branches sorted by their
    distance to it, the valid ones first, with ``valid`` in the same order
    (:func:`order_numpy`, or the compiled kernel's twin where it is installed: the same
    bits)."""
    try:
        ref = np.broadcast_to(real_array(near, "near"), (*q.shape[:-2], 6))
    except ValueError:
        raise InputError(
            f"near must be (..., 6) joint values that broadcast against the targets' batch "
            f"shape {q.shape[:-2]}, got shape {np.shape(near)}"
        ) from None
    if not np.all(np.isfinite(ref)):
        raise InputError("near contains NaN or inf; every value must be finite")
    k = q.shape[-2]
    args = (
        np.ascontiguousarray(q.reshape(-1, k, 6), dtype=np.float64),
        np.ascontiguousarray(valid.reshape(-1, k), dtype=np.bool_),
        np.ascontiguousarray(ref.reshape(-1, 6), dtype=np.float64),
        np.ascontiguousarray(chain.limits, dtype=np.float64),
        np.array([t == "revolute" for t in chain.joint_types], dtype=np.bool_),
    )
    q_sorted, valid_sorted = order_numpy(*args) if _kernel is None else _kernel.ordered(*args)
    return q_sorted.reshape(q.shape), valid_sorted.reshape(valid.shape)


def order_numpy(
    q: FloatArray, valid: BoolArray, ref: FloatArray, limits: FloatArray, revolute: BoolArray
) -> tuple[FloatArray, BoolArray]:
    """The reference of :func:`_ordered`: ``q (N, k, J)`` with each revolute angle moved to its
    equivalent nearest ``ref (N, J)`` within ``limits (J, 2)``
    (:func:`poekin.ik._angles.nearest_turns`), and each target's ``k`` branches sorted
    stably, the ``valid (N, k)`` ones first, then by their squared distance to ``ref``, summed
    joint by joint in order (what the kernel's twin sums). Returns the sorted ``q`` and
    ``valid``."""
    moved = nearest_turns(q, ref[:, None, :], limits, revolute)
    diff = moved - ref[:, None, :]
    d2 = diff[..., 0] * diff[..., 0]
    for j in range(1, q.shape[-1]):
        d2 = d2 + diff[..., j] * diff[..., j]
    order = np.lexsort((d2, ~valid), axis=-1)
    return (
        np.take_along_axis(moved, order[..., None], axis=-2),
        np.take_along_axis(valid, order, axis=-1),
    )


def solve_kernel(chain: Chain, T: FloatArray) -> tuple[FloatArray, BoolArray] | None:
    """The compiled twin of :func:`solve_numpy`: ``q`` ``(n, k, 6)`` and ``valid`` ``(n, k)``
    for ``(..., 4, 4)`` float64 targets, or None without the compiled kernel. Raises
    :class:`InputError` as :func:`_targets` does."""
    return _solve_kernel(geometry(chain), chain, _as_poses(T))


def _solve_kernel(
    geo: Geometry, chain: Chain, T: FloatArray
) -> tuple[FloatArray, BoolArray] | None:
    if _kernel is None:
        return None
    plain = np.require(T, requirements=("C", "A"))  # as the kernel reads it: a copy if not
    q, valid, bad = _kernel.ik_all(geo._kind, geo._params, plain, chain.limits)
    if bad >= 0:
        _targets(T)  # raises, saying what is wrong
        raise InputError(f"target pose {bad} is not a rigid transform")
    return q, valid


def solve_numpy(chain: Chain, T: FloatArray) -> tuple[FloatArray, BoolArray]:
    """The reference path: ``q`` ``(n, k, 6)`` and ``valid`` ``(n, k)`` for validated
    ``(n, 4, 4)`` targets ``T``."""
    return _solve_numpy(geometry(chain), chain, T)


def _solve_numpy(geo: Geometry, chain: Chain, T: FloatArray) -> tuple[FloatArray, BoolArray]:
    n, k = len(T), geo.n_solutions
    cols = np.ascontiguousarray(T.reshape(n, 16).T)
    R = ((cols[0], cols[1], cols[2]), (cols[4], cols[5], cols[6]), (cols[8], cols[9], cols[10]))
    found = geo._solve(_Target(R, (cols[3], cols[7], cols[11])))
    shape = np.broadcast_shapes(*(np.shape(a.c) for a in found.angles))
    q = np.empty((*shape, 6))
    for i, a in enumerate(found.angles):
        q[..., i] = np.arctan2(a.s, a.c)
    limits = chain.limits
    assert limits is not None  # Chain.__post_init__ sets them
    q = wrap_into_limits(q.reshape(n, k, 6), limits, np.ones(6, dtype=np.bool_))
    exists = np.broadcast_to(found.exists, shape).reshape(n, k)
    return q, exists & within_limits(q, limits)
