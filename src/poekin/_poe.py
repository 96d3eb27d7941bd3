"""Product of Exponentials entry by entry: the chain's constants as the reference path uses them.

What :class:`poekin.Chain` and its solvers (:mod:`poekin.ik`) share, so that neither imports the
other: the screws' constants (:class:`_ScrewTerms`), :func:`poe` and :func:`space_jacobian`
(the reference path, which the compiled kernel repeats operation for operation), a chain's
constants (:class:`_Model`) and parameters (:class:`ChainParams`), the validation of joint
values, and what the IK solvers need of a chain besides its screws (:class:`ChainTerms`,
computed with the chain).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _pose, lie
from poekin.errors import InputError

if TYPE_CHECKING:
    from poekin.chain import Chain

__all__ = [
    "ChainParams",
    "ChainTerms",
    "Column",
    "Trig",
    "as_joint_values",
    "chain_terms",
    "check_shape",
    "keep_chain_terms",
    "poe",
    "pose_of",
    "real_array",
    "space_jacobian",
    "world_columns",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _shown(x: object) -> str:
    """``repr(x)`` on one line, cut to 60 characters."""
    text = " ".join(repr(x).split())
    return text if len(text) <= 60 else text[:57] + "..."


def real_array(x: ArrayLike, what: str) -> FloatArray:
    """``x`` as a float64 array: the one conversion of every array poekin takes from its user
    (joint values, targets, measurements). Integers, booleans and float32 are converted;
    anything that is not a real number (``None``, text, objects, ragged lists, complex numbers:
    never cast to their real part) raises :class:`~poekin.errors.InputError`, ``what`` naming
    the values. Shape and finiteness are the caller's to check."""
    try:
        raw = np.asarray(x)
    except (TypeError, ValueError) as e:  # ragged nested lists
        raise InputError(f"{what} must be numbers, got {_shown(x)}") from e
    values = list(raw.flat) if raw.dtype.kind in "OUS" else []
    not_number = [v for v in values if v is None or isinstance(v, str | bytes)]
    if not_number:
        bad = not_number[0].item() if isinstance(not_number[0], np.generic) else not_number[0]
        raise InputError(f"{what} must be numbers, got {bad!r} in {_shown(x)}")
    if raw.dtype.kind == "c" or any(isinstance(v, complex | np.complexfloating) for v in values):
        raise InputError(
            f"{what} must be real numbers, got complex numbers; pass their real part "
            "(numpy.real) if that is what you mean"
        )
    try:
        return np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError) as e:  # objects that are no numbers
        raise InputError(f"{what} must be numbers, got {_shown(x)}") from e


def as_joint_values(
    q: ArrayLike, n: int, *, what: str = "joint values", layout: str = ""
) -> FloatArray:
    """Validate joint values ``q`` of shape ``(..., n)`` and return them as float64.

    Integers, booleans and float32 are accepted and converted. Anything that is not a real
    number (``None``, text, complex numbers: never cast to their real part), a wrong last axis,
    NaN or inf raises :class:`~poekin.errors.InputError`; ``what`` names the values in the
    message, and ``layout`` (if given) is appended to a wrong-shape message.
    """
    arr = real_array(q, what)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise InputError(
            f"expected {n} {what} (shape (..., {n})), got an array of shape {arr.shape}"
            + (f"; {layout}" if layout else "")
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{what} contain NaN or inf; every value must be finite")
    return arr


class ChainParams(NamedTuple):
    """A chain's kinematic parameters as arrays of any library: leaves to differentiate.

    A named tuple, so JAX (a pytree) and PyTorch (``torch.func``, ``torch.compile``,
    ``torch.export``) take it as a container of two arrays with no registration. Leading batch
    axes broadcast against those of ``q``.

    Attributes:
        screws: ``(..., n, 6)`` space-frame screws ``S_i = [w; v]`` at ``q = 0``.
        home: ``(..., 4, 4)`` ``M = T_world_frame(q = 0)``.
    """

    screws: Any
    home: Any


@dataclasses.dataclass(frozen=True)
class _ScrewTerms:
    """Per-joint constants of ``exp([S] q)`` for unit screws ``S = [w; v]``, computed once.

    With ``|w| = 1`` (or ``w = 0, |v| = 1``), the rotation needs no small-angle branch
    (exact ``cos``/``sin`` entries about a coordinate axis, else Rodrigues) and neither does the
    Murray-Li-Sastry form of the translation::

        R = I + sin(q) W + (1 - cos q) W^2
        p = (r - R r) + q u,   r = w x v,   u = (w . v) w  (u = v if w = 0)

    ``r`` is the point of the axis nearest the origin, so, unlike the textbook
    ``G(q) v = (q I + (1 - cos q) W + (q - sin q) W^2) v``, no term grows with ``q`` and
    cancels: the rounding stays at the size of the robot, not of ``q`` times it.
    """

    w: FloatArray  # (n, 3) rotation axes (0 for a prismatic screw)
    r: FloatArray  # (n, 3) w x v
    u: FloatArray  # (n, 3) (w . v) w, or v for a prismatic screw

    @classmethod
    def of(cls, screws: FloatArray) -> _ScrewTerms:
        w, v = screws[:, :3], screws[:, 3:]
        revolute = np.linalg.norm(w, axis=-1, keepdims=True) > 0
        u = np.where(revolute, np.sum(w * v, axis=-1, keepdims=True) * w, v)
        return cls(w, np.cross(w, v), u)

    def joints(self) -> tuple[_Screw, ...]:
        """The screws as the reference path applies them, constants as Python floats: a joint
        about a coordinate axis (:func:`poekin.lie.coordinate_axis`) turns by ``cos`` and
        ``+-sin`` entries, as the kernel's AXIS operations do."""
        out = []
        Ws = lie.hat_so3(self.w)  # every joint's at once (entry by entry, as one at a time)
        W2s = lie.rotate_compose(Ws, Ws)
        for w, r, u, W, W2 in zip(self.w, self.r, self.u, Ws, W2s, strict=True):
            out.append(
                _Screw(
                    axis=lie.coordinate_axis(w),
                    prismatic=not w.any(),
                    W=_floats(W),
                    W2=_floats(W2),
                    r=tuple(float(x) for x in r),  # type: ignore[arg-type]
                    u=tuple(float(x) for x in u),  # type: ignore[arg-type]
                )
            )
        return tuple(out)


def _floats(M: NDArray[np.floating[Any]]) -> _pose.Mat:
    return tuple(tuple(float(x) for x in row) for row in M)  # type: ignore[return-value]


@dataclasses.dataclass(frozen=True)
class _Screw:
    """One joint's ``exp([S] q)`` as the reference path applies it (see :class:`_ScrewTerms`).

    ``axis``: ``(k, sign)`` if ``w = sign e_k`` and the constants are the model's own (then
    ``cos``/``sin`` entries), None for Rodrigues with ``W = [w]`` and ``W2 = W W``. Entries
    are Python floats for a model's constants, arrays for differentiable parameters.
    """

    axis: tuple[int, float] | None
    prismatic: bool
    W: _pose.Mat
    W2: _pose.Mat
    r: _pose.Vec
    u: _pose.Vec


def _traced_screws(S: Sequence[Sequence[Any]], prismatic: Sequence[bool]) -> tuple[_Screw, ...]:
    """The screws ``S`` (rows of six entries, arrays) as :class:`_Screw`, in the general form
    only: no shortcut may depend on the values of parameters that are differentiated."""
    out = []
    for row, slide in zip(S, prismatic, strict=True):
        w, v = tuple(row[:3]), tuple(row[3:])
        W = _pose.hat(w)
        if slide:
            u = v
        else:
            wv = (w[0] * v[0] + w[1] * v[1]) + w[2] * v[2]
            u = (wv * w[0], wv * w[1], wv * w[2])
        out.append(_Screw(None, slide, W, _pose.mat_mat(W, W), _pose.cross(w, v), u))  # type: ignore[arg-type]
    return tuple(out)


def _turn(pose: _pose.Pose, screw: _Screw, th: Any, s: Any, c: Any) -> _pose.Pose:
    """``pose exp([S] th)`` given ``s = sin th`` and ``c = cos th``: the kernel's SCREW, AXIS
    or AXIS_PITCH operation."""
    if screw.prismatic:  # R = I: only the point moves, by th u
        R, p = pose
        moved = _pose.mat_vec(R, (th * screw.u[0], th * screw.u[1], th * screw.u[2]))
        return R, (p[0] + moved[0], p[1] + moved[1], p[2] + moved[2])
    if screw.axis is not None:
        k, sign = screw.axis
        along = th * screw.u[k] if screw.u[k] != 0.0 else None  # a pitched screw advances
        return _pose.axis_turn(pose, k, sign * s, c, screw.r, along)
    R_j = _pose.rodrigues(screw.W, screw.W2, s, 1.0 - c)
    t_j = _pose.about_point(R_j, screw.r)
    t_j = (t_j[0] + th * screw.u[0], t_j[1] + th * screw.u[1], t_j[2] + th * screw.u[2])
    return _pose.compose(pose, R_j, t_j)


Trig = Callable[[Sequence[Any], Any], tuple[list[Any], list[Any]]]


def _turns(
    screws: Sequence[_Screw], q: Sequence[Any], xp: Any, trig: Trig = _pose.sincos
) -> list[tuple[_Screw, Any, Any, Any]]:
    """Each screw with its angle, sine and cosine (computed once by ``trig``:
    :func:`_pose.sincos`, or the compiled kernel's own, :func:`poekin.kernel._sincos.sincos`)."""
    turning = [i for i, screw in enumerate(screws) if not screw.prismatic]
    sines, cosines = trig([q[i] for i in turning], xp)
    s: list[Any] = [None] * len(screws)
    c: list[Any] = [None] * len(screws)
    for i, si, ci in zip(turning, sines, cosines, strict=True):
        s[i], c[i] = si, ci
    return list(zip(screws, q, s, c, strict=True))


def poe(
    screws: Sequence[_Screw],
    q: Sequence[Any],
    xp: Any,
    *,
    left: _pose.Pose | None = None,
    right: _pose.Pose | None = None,
) -> _pose.Pose:
    """``left exp([S_1] q_1) ... exp([S_n] q_n) right`` for unit screws, entry by entry.

    The reference path for every array library; the compiled kernel does the same arithmetic
    in the same order.

    Args:
        screws: the joints' constants, see :class:`_Screw`.
        q: ``n`` entries, each joint's values (arrays of the batch shape).
        xp: the arrays' namespace (``numpy`` for NumPy).
        left, right: constant poses, or None for the identity.

    Returns:
        The pose as entries (:mod:`poekin._pose`).
    """
    pose: _pose.Pose = (_pose.IDENTITY, _pose.ORIGIN)
    if left is not None:
        pose = _pose.compose_const(pose, *left)
    for screw, th, s, c in _turns(screws, q, xp):
        pose = _turn(pose, screw, th, s, c)
    if right is not None:
        pose = _pose.compose_const(pose, *right)
    return pose


Column = tuple[Any, Any, Any, Any, Any, Any]


def space_jacobian(
    screws: Sequence[_Screw],
    S: Sequence[Sequence[Any]],
    q: Sequence[Any],
    xp: Any,
    home: _pose.Pose,
    trig: Trig = _pose.sincos,
) -> tuple[list[Column], _pose.Pose]:
    """The space Jacobian's columns and the end pose ``T = exp([S_1] q_1) ... M``.

    Column ``i`` is ``Ad(T_{i-1}) S_i = [R w; p x R w + R v]`` with ``T_{i-1} = (R, p) =
    exp([S_1] q_1) ... exp([S_{i-1}] q_{i-1})``, rows ``[w; v]``; the partial products are
    those of :func:`poe`. ``trig`` computes the sines and cosines (see :func:`_turns`).
    """
    pose: _pose.Pose = (_pose.IDENTITY, _pose.ORIGIN)
    columns: list[Column] = []
    for (screw, th, s, c), S_i in zip(_turns(screws, q, xp, trig), S, strict=True):
        R, p = pose
        a = _pose.mat_vec(R, S_i[:3])
        lever, Rv = _pose.cross(p, a), _pose.mat_vec(R, S_i[3:])
        columns.append((*a, lever[0] + Rv[0], lever[1] + Rv[1], lever[2] + Rv[2]))
        pose = _turn(pose, screw, th, s, c)
    return columns, _pose.compose_const(pose, *home)


def world_columns(columns: Sequence[Column], p: _pose.Vec) -> list[Column]:
    """Space columns ``[w; v]`` as world columns ``[w; v + w x p]`` for the frame at ``p``."""
    out = []
    for c in columns:
        wp = _pose.cross(c[:3], p)
        out.append((c[0], c[1], c[2], c[3] + wp[0], c[4] + wp[1], c[5] + wp[2]))
    return out


def pose_of(T: Any) -> _pose.Pose:
    """The pose entries of a ``(..., 4, 4)`` array, or of a constant ``(4, 4)`` NumPy array as
    Python floats."""
    if isinstance(T, np.ndarray) and T.ndim == 2:
        T = T.tolist()
        return (tuple(tuple(row[:3]) for row in T[:3]), tuple(row[3] for row in T[:3]))  # type: ignore[return-value]
    return (
        tuple(tuple(T[..., i, j] for j in range(3)) for i in range(3)),  # type: ignore[return-value]
        tuple(T[..., i, 3] for i in range(3)),
    )


class _Model(NamedTuple):
    """A chain's constants as the reference path uses them."""

    screws: tuple[_Screw, ...]  # space screws
    rows: Sequence[Sequence[Any]]  # the space screws' six entries each (Jacobian columns)
    home: _pose.Pose
    body: tuple[_Screw, ...]  # body screws


def check_shape(a: Any, trailing: tuple[int, ...], name: str) -> None:
    """:class:`InputError` unless ``a``'s trailing axes are ``trailing``."""
    shape = tuple(a.shape)
    if len(shape) < len(trailing) or shape[len(shape) - len(trailing) :] != trailing:
        expected = ", ".join(map(str, trailing))
        raise InputError(f"{name} must have shape (..., {expected}), got {shape}")


@dataclasses.dataclass(frozen=True)
class ChainTerms:
    """What the IK solvers need of a chain besides its screws (computed once per chain).

    ``start_base + u start_span`` is a random start for ``u`` uniform in ``[0, 1)``: uniform
    within finite limits, ``(-pi, pi]`` for an unlimited revolute joint, a turn (or ``L``
    metres) from a one-sided limit, ``[-L, L)`` for an unlimited prismatic joint.

    The per-iteration functions read the Python values (``bounds``, ``turns``, ``base``,
    ``span``), never the NumPy arrays, so that code traced by JAX or torch.compile sees
    constants.
    """

    limits: FloatArray  # (n, 2)
    revolute: BoolArray  # (n,)
    cyclic: BoolArray  # (n,) revolute without limits: kept in (-pi, pi]
    start_base: FloatArray  # (n,)
    start_span: FloatArray  # (n,)
    scale: float  # L (m): the distance from the home frame to the farthest joint axis, >= 0.1
    bounds: tuple[tuple[float, float], ...]  # the limits (lower, upper)
    turns: tuple[bool, ...]  # revolute
    base: tuple[float, ...]  # start_base
    span: tuple[float, ...]  # start_span


def chain_terms(chain: Chain, single: bool = False) -> ChainTerms:
    """The chain's :class:`ChainTerms` (kept with the chain: :meth:`poekin.Chain.__post_init__`
    computes them, as torch.compile cannot trace their NumPy); ``single``: for a float32
    solve, the bounds rounded inwards to float32 values, so that an answer within them in
    float32 is within the model's limits."""
    terms: ChainTerms = chain._ik_cache["terms32" if single else "terms"]
    return terms


def keep_chain_terms(chain: Chain) -> None:
    """Compute the chain's :class:`ChainTerms` (both) into its IK cache."""
    terms = _chain_terms(chain)
    lo32 = terms.limits.astype(np.float32)
    up, down = np.float32(np.inf), np.float32(-np.inf)
    inward = np.where(
        np.arange(2) == 0,
        np.where(lo32 < terms.limits, np.nextafter(lo32, up), lo32),
        np.where(lo32 > terms.limits, np.nextafter(lo32, down), lo32),
    ).astype(np.float64)
    chain._ik_cache["terms"] = terms
    chain._ik_cache["terms32"] = dataclasses.replace(
        terms, bounds=tuple((float(a), float(b)) for a, b in inward)
    )


def _chain_terms(chain: Chain) -> ChainTerms:
    assert chain.limits is not None  # Chain sets them (infinite where there are none)
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    revolute = np.array([t == "revolute" for t in chain.joint_types], dtype=bool)
    cyclic = revolute & np.isneginf(lo) & np.isposinf(hi)
    w, v = chain.screws[:, :3], chain.screws[:, 3:]
    points = np.cross(w, v)  # the point of each revolute axis nearest the origin
    reach = np.linalg.norm(chain.home[:3, 3] - points[revolute], axis=-1)
    scale = max(0.1, float(reach.max()) if reach.size else 0.0)
    turn = np.where(revolute, math.tau, scale)
    base = np.where(np.isfinite(lo), lo, np.where(np.isfinite(hi), hi, -turn / 2))
    span = np.where(np.isfinite(lo) & np.isfinite(hi), hi - lo, turn)
    span = np.where(np.isneginf(lo) & np.isfinite(hi), -turn, span)
    base = np.where(cyclic, np.pi, base)
    span = np.where(cyclic, -math.tau, span)
    for a in (base, span):
        a.flags.writeable = False
    return ChainTerms(
        chain.limits,
        revolute,
        cyclic,
        base,
        span,
        scale,
        tuple((float(a), float(b)) for a, b in chain.limits),
        tuple(bool(x) for x in revolute),
        tuple(float(x) for x in base),
        tuple(float(x) for x in span),
    )
