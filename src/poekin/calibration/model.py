"""The calibration model: a chain's geometry as local corrections, complete and minimal.

The robot as measured is::

    T_meas_frame(q) = B exp([S'_1] (q_1 + o_1)) ... exp([S'_n] (q_n + o_n)) M'

in the measuring frame (a laser tracker's, a camera's), with the encoder readings ``q``. Its
parameters are corrections of the nominal chain (screws ``S_i``, home ``M``), in the chain's
own base frame at ``q = 0``:

* ``B``: the robot base in the measuring frame (6: rotation about the base's x, y, z through
  its origin, then a shift along them);
* ``o_i``: each joint's encoder offset (rad, or m for a prismatic joint);
* the tool ``M' = [R_M exp([phi]), p_M + R_M t]``: a shift ``t`` and a rotation ``phi`` in the
  end frame's own axes (only ``t`` with positions-only data: a point has no orientation);
* each revolute joint's axis line: its direction tilted about two directions ``a_i``, ``b_i``
  normal to it, ``w' = exp([theta_a a_i + theta_b b_i]) w_i``, and its point ``p_i`` (from
  :func:`poekin.dh.joint_lines`) shifted along them, ``p' = p_i + c_a a_i + c_b b_i`` (4);
  a prismatic joint's direction only (2). ``a_i`` lies along the common normal of joints
  ``i - 1`` and ``i`` (the direction from one to the other if they are parallel), as a DH
  table's x axis does, and ``b_i = w_i x a_i``.

PoE has no DH singularity: parallel axes are ordinary. These ``5R + 3P + 12`` corrections are
redundant: moving the robot's base frame (6) or an encoder zero (``n``: ``exp([S_i] o_i)`` is
absorbed by the later joints and the tool) changes nothing measurable. The minimal set that is
fitted is chosen from the structure alone (the nominal chain, no measurement): the full
identification Jacobian on random configurations, with columns taken greedily, each kept if it
adds a direction, in this order of preference: the base, the encoder offsets, the tool, then
the joints' lines from the last to the first. So the base keeps all 6, joint 1's offset and
line go into the base, each joint's offset keeps the DH theta role (joint ``i + 1``'s place
about axis ``i`` stays the model's), and what is left is ``4R + 2P + 6`` (30 for a 6R arm, 34
for a 7R; 3 fewer with positions only), the count of Okamura & Park / Zhuang.

Lengths are metres, angles radians.
"""

from __future__ import annotations

import dataclasses
import functools
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from poekin._poe import _ScrewTerms
from poekin.chain import Chain
from poekin.dh import joint_lines
from poekin.errors import InputError
from poekin.lie import _one_minus_cos_over_t2, _sin_over_t, _t_minus_sin_over_t3

if TYPE_CHECKING:
    from poekin.io.sources import LoadedModel

__all__ = [
    "MEASURES",
    "CalibrationModel",
    "Measure",
    "Parameter",
    "Redundancy",
    "State",
    "as_chain",
    "expected_identifiable",
    "model_of",
]

FloatArray = NDArray[np.float64]
Measure = Literal["pose", "position"]
MEASURES: tuple[Measure, ...] = ("pose", "position")

# Structural selection: configurations and the relative size below which a column adds nothing.
_STRUCTURE_SAMPLES = 48
_STRUCTURE_SEED = 20240611
_DEPENDENT = 1e-7
_PARALLEL = 1e-8  # |w_{i-1} x w_i| below this: parallel axes
_AXES = "xyz"


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One correction: ``key`` (``"base.rz"``, ``"elbow_joint.offset"``), ``group`` (``base``,
    ``offset``, ``tool``, ``tilt``, ``shift``), the joint it belongs to (0-based, None for the base
    and the tool), its unit (``m`` or ``rad``) and what it is, in words."""

    key: str
    group: str
    joint: int | None
    unit: str
    words: str


@dataclasses.dataclass(frozen=True)
class Redundancy:
    """A correction left out of the fit because others move the tool alike (``alike``, their
    indices into :attr:`CalibrationModel.params`; empty when it moves nothing measured)."""

    param: int
    alike: tuple[int, ...]


@dataclasses.dataclass(frozen=True)
class State:
    """A point of the model: the base ``B = T_meas_base`` ``(4, 4)`` and the other corrections
    ``x`` ``(P,)`` (entries of the base are unused: the base is kept as a pose)."""

    base: FloatArray
    x: FloatArray


def expected_identifiable(chain: Chain, measure: Measure) -> int:
    """``4R + 2P + 6`` parameters with full poses, 3 fewer with positions only."""
    revolute = sum(t == "revolute" for t in chain.joint_types)
    count = 4 * revolute + 2 * (chain.n_joints - revolute) + 6
    return count - (3 if measure == "position" else 0)


def _normal(w: FloatArray) -> FloatArray:
    """A unit vector normal to unit ``w``."""
    e = np.zeros(3)
    e[int(np.argmin(np.abs(w)))] = 1.0
    a = np.cross(w, e)
    return np.asarray(a / np.linalg.norm(a), dtype=np.float64)


def _bases(dirs: FloatArray, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``a_i`` along the common normal of axes ``i - 1`` and ``i`` (or from one parallel axis
    to the other), ``b_i = w_i x a_i``; see the module docstring."""
    n = len(dirs)
    a, b = np.zeros((n, 3)), np.zeros((n, 3))
    for i in range(n):
        w = dirs[i]
        ai = None
        if i > 0:
            c = np.cross(dirs[i - 1], w)
            if np.linalg.norm(c) > _PARALLEL:
                ai = c / np.linalg.norm(c)
            else:
                r = points[i] - points[i - 1]
                r = r - w * (r @ w)
                if np.linalg.norm(r) > 1e-9:
                    ai = r / np.linalg.norm(r)
        a[i] = _normal(w) if ai is None else ai
        b[i] = np.cross(w, a[i])
    return a, b


def _right_jacobian(theta: FloatArray) -> FloatArray:
    """SO(3)'s right Jacobian ``J_r(theta) = I - (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2``:
    ``exp([theta + d]) = exp([theta]) exp([J_r d])`` to first order. ``(..., 3) -> (..., 3, 3)``."""
    t = np.linalg.norm(theta, axis=-1)[..., None, None]
    W = _hat(theta)
    return np.asarray(
        np.eye(3) - _one_minus_cos_over_t2(t) * W + _t_minus_sin_over_t3(t) * (W @ W),
        dtype=np.float64,
    )


def rotations(v: FloatArray) -> FloatArray:
    """``(..., 3) -> (..., 3, 3)`` ``exp([v])``: Rodrigues' ``I + sin(t)/t W + (1 - cos t)/t^2
    W^2`` with :mod:`poekin.lie`'s coefficients, as matrix products (NumPy only, for the fit's
    many small turns; :func:`poekin.lie.exp_so3` takes every array library)."""
    t = np.linalg.norm(v, axis=-1)[..., None, None]
    W = _hat(v)
    return np.asarray(
        np.eye(3) + _sin_over_t(t) * W + _one_minus_cos_over_t2(t) * (W @ W),
        dtype=np.float64,
    )


def _cross(a: FloatArray, b: FloatArray, axis: int = -1) -> FloatArray:
    """``a x b`` along ``axis`` (-1, or -2 for stacks of columns ``(..., 3, K)``): NumPy's
    ``cross`` without its overhead on small arrays."""
    if axis == -2:
        a0, a1, a2 = a[..., 0, :], a[..., 1, :], a[..., 2, :]
        b0, b1, b2 = b[..., 0, :], b[..., 1, :], b[..., 2, :]
    else:
        a0, a1, a2, b0, b1, b2 = a[..., 0], a[..., 1], a[..., 2], b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=axis)


def _hat(v: FloatArray) -> FloatArray:
    """``(..., 3) -> (..., 3, 3)`` skew matrices (NumPy only; :func:`poekin.lie.hat_so3` takes
    every array library)."""
    W = np.zeros((*v.shape[:-1], 3, 3))
    W[..., 0, 1], W[..., 0, 2], W[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    W[..., 1, 0], W[..., 2, 0], W[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return W


def _exponentials(terms: _ScrewTerms, theta: FloatArray) -> FloatArray:
    """``(N, n, 4, 4)`` ``exp([S_i] theta_i)`` of unit screws, in the form of
    :class:`poekin._poe._ScrewTerms` (whose constants they are): ``R = I + sin W + (1 - cos)
    W^2``, ``p = r - R r + theta u`` (a prismatic screw: ``W = 0``, ``r = 0``, ``u = v``),
    evaluated for every joint and pose at once."""
    W = _hat(terms.w)  # (n, 3, 3)
    s, c = np.sin(theta)[..., None, None], np.cos(theta)[..., None, None]
    R = np.eye(3) + s * W + (1.0 - c) * (W @ W)
    E = np.zeros((*theta.shape, 4, 4))
    E[..., :3, :3] = R
    E[..., :3, 3] = terms.r - (R @ terms.r[:, :, None])[..., 0] + theta[..., None] * terms.u
    E[..., 3, 3] = 1.0
    return E


def _adjoint(T: FloatArray) -> FloatArray:
    """``(..., 4, 4) -> (..., 6, 6)`` the adjoint ``[[R, 0], [[p] R, R]]`` (twists ``[w; v]``;
    NumPy only, as :func:`_hat`; :func:`poekin.lie.adjoint` takes every array library)."""
    R = T[..., :3, :3]
    A = np.zeros((*T.shape[:-2], 6, 6))
    A[..., :3, :3] = R
    A[..., 3:, 3:] = R
    A[..., 3:, :3] = _hat(T[..., :3, 3]) @ R
    return A


@dataclasses.dataclass(frozen=True)
class Geometry:
    """The corrected robot in its base frame at ``q = 0`` (:meth:`CalibrationModel.geometry`):
    joint directions and points ``(n, 3)``, offsets ``(n,)``, screws ``(n, 6)``, home ``M'``,
    and, for the Jacobian, each joint's tilt rotation and its right Jacobian ``(n, 3, 3)``, the
    tool's turn ``phi`` ``(3,)`` and its right Jacobian; and the screws' terms
    (:class:`poekin._poe._ScrewTerms`) for :meth:`CalibrationModel.products`."""

    dirs: FloatArray
    points: FloatArray
    offsets: FloatArray
    screws: FloatArray
    home: FloatArray
    turn: FloatArray
    vectors: FloatArray  # (n + 1, 3): the joints' tilt vectors, then the tool's turn
    terms: _ScrewTerms

    @functools.cached_property
    def _jacobians(self) -> FloatArray:
        return _right_jacobian(self.vectors)

    @property
    def turn_jacobian(self) -> FloatArray:
        return self._jacobians[:-1]

    @property
    def tool_turn(self) -> FloatArray:
        return np.asarray(self.vectors[-1], dtype=np.float64)

    @property
    def tool_turn_jacobian(self) -> FloatArray:
        return np.asarray(self._jacobians[-1], dtype=np.float64)


@dataclasses.dataclass(frozen=True, eq=False)
class CalibrationModel:
    """The corrections of ``chain`` for ``measure`` data, and the minimal set that is fitted.

    Attributes:
        chain: the nominal chain (its world frame is the robot's base frame).
        measure: ``"pose"`` (position and orientation measured) or ``"position"``.
        params: every correction, in the order of preference (see the module docstring).
        free: the indices of the minimal, complete set that is fitted.
        redundant: the others, with the corrections that move the tool alike.
    """

    chain: Chain
    measure: Measure
    params: tuple[Parameter, ...]
    free: tuple[int, ...]
    redundant: tuple[Redundancy, ...]
    dirs: FloatArray
    points: FloatArray
    a: FloatArray
    b: FloatArray
    offset_index: tuple[int, ...]
    line_index: tuple[tuple[int, ...], ...]
    tool_shift_index: tuple[int, ...]
    tool_turn_index: tuple[int, ...]
    _geometries: dict[bytes, Geometry] = dataclasses.field(
        default_factory=dict, repr=False, compare=False
    )

    @classmethod
    def of(cls, chain: Chain, measure: Measure = "pose") -> CalibrationModel:
        """The model of ``chain``, with its minimal set chosen from the structure."""
        dirs, points = joint_lines(chain)
        a, b = _bases(dirs, points)
        params: list[Parameter] = []

        def add(key: str, group: str, joint: int | None, unit: str, words: str) -> int:
            params.append(Parameter(key, group, joint, unit, words))
            return len(params) - 1

        for k in range(3):
            add(
                f"base.r{_AXES[k]}",
                "base",
                None,
                "rad",
                f"the base's rotation about its {_AXES[k]}",
            )
        for k in range(3):
            add(f"base.{_AXES[k]}", "base", None, "m", f"the base's shift along its {_AXES[k]}")
        shifts = tuple(
            add(f"tool.{_AXES[k]}", "tool", None, "m", f"the tool's shift along its {_AXES[k]}")
            for k in range(3)
        )
        names = chain.joint_names
        label = [f"joint {i + 1} ({name})" for i, name in enumerate(names)]
        offsets = tuple(
            add(
                f"{name}.offset",
                "offset",
                i,
                "rad" if chain.joint_types[i] == "revolute" else "m",
                f"{label[i]}'s encoder offset",
            )
            for i, name in enumerate(names)
        )
        turns: tuple[int, ...] = ()
        if measure == "pose":
            turns = tuple(
                add(
                    f"tool.r{_AXES[k]}",
                    "tool",
                    None,
                    "rad",
                    f"the tool's turn about its {_AXES[k]}",
                )
                for k in range(3)
            )
        lines: list[tuple[int, ...]] = [()] * chain.n_joints
        for i in reversed(range(chain.n_joints)):
            name = names[i]
            about = [_direction(a[i]), _direction(b[i])]
            keys: list[int] = []
            if chain.joint_types[i] == "revolute":
                keys += [
                    add(f"{name}.shift_{ab}", "shift", i, "m", f"{label[i]}'s axis shift along {d}")
                    for ab, d in zip("ab", about, strict=True)
                ]
            keys += [
                add(f"{name}.tilt_{ab}", "tilt", i, "rad", f"{label[i]}'s axis tilt about {d}")
                for ab, d in zip("ab", about, strict=True)
            ]
            lines[i] = tuple(keys)
        model = cls(
            chain=chain,
            measure=measure,
            params=tuple(params),
            free=tuple(range(len(params))),
            redundant=(),
            dirs=dirs,
            points=points,
            a=a,
            b=b,
            offset_index=offsets,
            line_index=tuple(lines),
            tool_shift_index=shifts,
            tool_turn_index=turns,
        )
        free, redundant = model._structure()
        return dataclasses.replace(model, free=free, redundant=redundant)

    @property
    def n_params(self) -> int:
        return len(self.params)

    def units(self, keys: Sequence[int], prior_m: float, prior_rad: float) -> FloatArray:
        """``(len(keys),)`` each correction's prior: ``prior_m`` for a length, ``prior_rad``
        for an angle (the units the fit weighs corrections in)."""
        return np.array([prior_m if self.params[k].unit == "m" else prior_rad for k in keys])

    @property
    def rows_per_pose(self) -> int:
        """Measured numbers per pose: 6 (orientation and position) or 3 (position)."""
        return 6 if self.measure == "pose" else 3

    def nominal(self, base: FloatArray | None = None) -> State:
        """The model's own geometry (every correction 0), at ``base`` (identity if None)."""
        B = np.eye(4) if base is None else np.asarray(base, dtype=np.float64)
        return State(B, np.zeros(self.n_params))

    # --- geometry ---------------------------------------------------------------------------

    def geometry(self, x: FloatArray) -> Geometry:
        """The corrected robot for corrections ``x`` (the last few are remembered: a fit asks
        for the same ones for its residuals and then its Jacobian)."""
        key = x.tobytes()
        cache = self._geometries
        if key not in cache:
            if len(cache) >= 4:
                cache.pop(next(iter(cache)))
            cache[key] = self._geometry(x)
        return cache[key]

    def _geometry(self, x: FloatArray) -> Geometry:
        slots = self._slots
        values = np.where(slots >= 0, x[np.maximum(slots, 0)], 0.0)  # (n, 4)
        a, b = self.a, self.b
        shift = values[:, :1] * a + values[:, 1:2] * b
        phi = x[list(self.tool_turn_index)] if self.tool_turn_index else np.zeros(3)
        # the joints' tilts and the tool's turn, as one batch
        vectors = np.concatenate([values[:, 2:3] * a + values[:, 3:4] * b, phi[None]])
        turns = rotations(vectors)
        dirs = (turns[:-1] @ self.dirs[:, :, None])[:, :, 0]
        points = self.points + shift
        prismatic = self.prismatic[:, None]
        w = np.where(prismatic, 0.0, dirs)
        v = np.where(prismatic, dirs, _cross(points, dirs))
        home = self.chain.home
        t = x[list(self.tool_shift_index)]
        M = np.eye(4)
        M[:3, :3] = home[:3, :3] @ turns[-1]
        M[:3, 3] = home[:3, 3] + home[:3, :3] @ t
        screws = np.concatenate([w, v], axis=1)
        return Geometry(
            dirs=dirs,
            points=points,
            offsets=x[list(self.offset_index)],
            screws=screws,
            home=M,
            turn=turns[:-1],
            vectors=vectors,
            terms=_ScrewTerms.of(screws),
        )

    @functools.cached_property
    def prismatic(self) -> NDArray[np.bool_]:
        return np.array([t == "prismatic" for t in self.chain.joint_types], dtype=bool)

    @functools.cached_property
    def _slots(self) -> NDArray[np.int_]:
        return np.asarray(self.line_slots, dtype=int)

    @property
    def line_slots(self) -> list[list[int]]:
        """Per joint, the indices of its corrections ``[shift_a, shift_b, tilt_a, tilt_b]``,
        -1 where it has none (a prismatic joint has no shifts)."""
        return [[-1, -1, *keys] if len(keys) == 2 else list(keys) for keys in self.line_index]

    def robot_chain(self, x: FloatArray) -> Chain:
        """The corrected robot in its own base frame, encoder offsets not applied."""
        geo = self.geometry(x)
        return dataclasses.replace(self.chain, screws=geo.screws, home=geo.home, qpos_indices=None)

    def calibrated_chain(self, state: State) -> Chain:
        """The calibrated chain: FK in the measuring frame for encoder readings ``q``.

        Offsets are absorbed: ``exp([S](q + o)) = exp([S] o) exp([S] q)``, and each
        ``exp([S_i] o_i)`` moves the later screws and the tool, so the screws become
        ``Ad(B G_i) S'_i`` and the home ``B G_n M'`` with ``G_i = exp([S'_1] o_1) ...
        exp([S'_i] o_i)``.
        """
        geo = self.geometry(state.x)
        S, M = geo.screws, geo.home
        E = _exponentials(geo.terms, geo.offsets[None])[0]  # exp([S'_i] o_i)
        G = np.asarray(state.base, dtype=np.float64).copy()
        screws = np.zeros_like(S)
        for i in range(len(S)):
            G = G @ E[i]
            screws[i] = _adjoint(G) @ S[i]
        # the screws' axes are unit up to rounding; renormalise so that the chain takes them
        for i, kind in enumerate(self.chain.joint_types):
            part = slice(0, 3) if kind == "revolute" else slice(3, 6)
            screws[i] /= np.linalg.norm(screws[i, part])
        return dataclasses.replace(self.chain, screws=screws, home=G @ M, qpos_indices=None)

    # --- forward kinematics and the identification Jacobian ---------------------------------

    def products(self, state: State, q: FloatArray) -> tuple[FloatArray, Geometry]:
        """Partial products ``(N, n + 1, 4, 4)``: ``P_0 = I``, ``P_{i+1} = P_i exp([S'_i](q_i +
        o_i))``; and the geometry."""
        geo = self.geometry(state.x)
        N, n = len(q), self.chain.n_joints
        E = _exponentials(geo.terms, q + geo.offsets)
        P = np.empty((N, n + 1, 4, 4))
        P[:, 0] = np.eye(4)
        for i in range(n):
            P[:, i + 1] = P[:, i] @ E[:, i]
        return P, geo

    def poses(self, state: State, q: FloatArray) -> FloatArray:
        """``(N, 4, 4)`` poses of the measured frame in the measuring frame."""
        P, geo = self.products(state, q)
        return np.asarray(state.base @ P[:, -1] @ geo.home, dtype=np.float64)

    def jacobian(self, state: State, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The poses ``(N, 4, 4)`` and the derivatives ``(N, 6, P)`` of the measured frame's
        rotation (rows 0-2, rad) and origin (rows 3-5, m), in the measuring frame, with respect
        to every correction (the base's: a turn of ``B`` about its own axes through its origin,
        then a shift along them).

        Each correction moves the robot (in its base frame) by a twist: the base by its own
        unit twists; an offset by joint ``i``'s space-Jacobian column ``Ad(P_i) S_i``; a motion
        ``eta`` of joint ``i``'s line (:meth:`_line_twists`) by ``Ad(P_i) eta - Ad(P_{i+1})
        eta``, since ``exp([Ad(G) S] q) = G exp([S] q) G^-1``; the tool by ``Ad(P_n M')`` of its
        body twist. ``Ad(B)`` turns them into the measuring frame.
        """
        return self.derivatives(state, *self.products(state, q))

    def derivatives(
        self, state: State, P: FloatArray, geo: Geometry
    ) -> tuple[FloatArray, FloatArray]:
        """:meth:`jacobian` from the partial products ``P`` and the geometry at ``state``
        (:meth:`products`), for a caller that has them already (a fit's trial step)."""
        N, n = len(P), self.chain.n_joints
        Ad = _adjoint(P)  # (N, n + 1, 6, 6): Ad(P_i)
        eta = self._line_twists(geo)  # (n, 6, 4)
        before = Ad[:, :n] @ np.concatenate([geo.screws[:, :, None], eta], axis=2)
        moved = before[..., 1:] - Ad[:, 1:] @ eta  # (N, n, 6, 4)
        xi = np.zeros((N, 6, self.n_params))  # twists in the robot's base frame
        xi[:, :, :6] = np.eye(6)
        xi[:, :, list(self.offset_index)] = before[..., 0].transpose(0, 2, 1)
        slots = np.asarray(self.line_slots).reshape(-1)
        xi[:, :, slots[slots >= 0]] = moved.transpose(0, 2, 1, 3).reshape(N, 6, 4 * n)[
            :, :, slots >= 0
        ]
        T_r = P[:, -1] @ geo.home
        body = np.zeros((6, 3 + len(self.tool_turn_index)))
        body[3:, :3] = geo.home[:3, :3].T @ self.chain.home[:3, :3]  # exp(-phi)
        if self.tool_turn_index:
            body[:3, 3:] = geo.tool_turn_jacobian
        xi[:, :, [*self.tool_shift_index, *self.tool_turn_index]] = _adjoint(T_r) @ body
        T = np.asarray(state.base @ T_r, dtype=np.float64)
        # into the measuring frame (Ad(B)), then the origin's velocity v + w x p:
        # [[R_B, 0], [([p_B] - [p]) R_B, R_B]]
        C = np.repeat(_adjoint(state.base)[None], N, axis=0)
        C[:, 3:, :3] -= _hat(T[:, :3, 3]) @ state.base[:3, :3]
        return T, np.asarray(C @ xi, dtype=np.float64)

    def _line_twists(self, geo: Geometry) -> FloatArray:
        """``(n, 6, 4)``: per joint, the rigid motions (twists at ``q = 0``) that move its line
        as its corrections ``[shift_a, shift_b, tilt_a, tilt_b]`` do, to first order (zero
        columns for a prismatic joint's shifts, which it has not).

        A shift moves the point: ``[0; a]``. A tilt turns the direction by
        ``dw = R(theta) ((J_r(theta) a) x w_0)``: the turn ``omega = w x dw`` about the line's
        point, ``[omega; p x omega]`` (``[omega; 0]`` for a prismatic joint, which has no point).
        """
        e = np.stack([self.a, self.b], axis=1)  # (n, 2, 3)
        Je = (geo.turn_jacobian[:, None] @ e[..., None])[..., 0]
        dw = (geo.turn[:, None] @ _cross(Je, self.dirs[:, None, :])[..., None])[..., 0]
        omega = _cross(np.broadcast_to(geo.dirs[:, None, :], dw.shape), dw)
        at = np.where(self.prismatic[:, None, None], 0.0, geo.points[:, None, :])
        eta = np.zeros((len(e), 6, 4))
        eta[:, 3:, 0], eta[:, 3:, 1] = self.a, self.b
        eta[self.prismatic, :, :2] = 0.0
        eta[:, :3, 2:] = omega.transpose(0, 2, 1)
        eta[:, 3:, 2:] = _cross(np.broadcast_to(at, omega.shape), omega).transpose(0, 2, 1)
        return eta

    # --- structure --------------------------------------------------------------------------

    def _structure(self) -> tuple[tuple[int, ...], tuple[Redundancy, ...]]:
        from poekin.verification.verify import sample_joint_values

        chain = self.chain
        assert chain.limits is not None  # a chain always has limits (+-inf if none)
        limits = np.clip(chain.limits, -np.pi, np.pi)
        q = sample_joint_values(
            dataclasses.replace(chain, limits=limits),
            _STRUCTURE_SAMPLES,
            seed=_STRUCTURE_SEED,
            within_limits=True,
        )
        state = self.nominal()
        if self.measure == "position":  # a point off every axis: see generic_point()
            x = state.x.copy()
            x[list(self.tool_shift_index)] = generic_point(chain)
            state = State(state.base, x)
        rows = self.rows(state, q)
        norms = np.linalg.norm(rows, axis=0)
        scale = np.where(norms > 0, norms, 1.0)
        A = rows / scale
        basis = np.zeros((A.shape[0], 0))
        kept: list[int] = []
        dropped: list[int] = []
        for k in range(self.n_params):
            c = A[:, k]
            r = c - basis @ (basis.T @ c)
            r = r - basis @ (basis.T @ r)
            if norms[k] > 0 and np.linalg.norm(r) > _DEPENDENT:
                kept.append(k)
                basis = np.column_stack([basis, r / np.linalg.norm(r)])
            else:
                dropped.append(k)
        redundant = tuple(
            Redundancy(k, alike(A[:, kept], A[:, k], kept) if norms[k] > 0 else ()) for k in dropped
        )
        return tuple(kept), redundant

    def rows(self, state: State, q: FloatArray) -> FloatArray:
        """The identification Jacobian ``(N m, P)`` in metres: rotation rows (pose data only)
        times the chain's reach, then position rows, pose by pose."""
        return self.in_metres(self.measured(self.jacobian(state, q)[1]))

    def measured(self, D: FloatArray) -> FloatArray:
        """The rows of derivatives ``(N, 6, K)`` (:meth:`jacobian`) that the data measure: all 6
        for poses, the position's 3 for positions: ``(N, m, K)``."""
        return D[:, 3:] if self.measure == "position" else D

    def in_metres(self, D: FloatArray) -> FloatArray:
        """Measured rows ``(N, m, K)`` (:meth:`measured`) as ``(N m, K)`` in metres: rotation
        rows (pose data) times the chain's reach."""
        if self.measure == "pose":
            D = np.concatenate([D[:, :3] * reach(self.chain), D[:, 3:]], axis=1)
        return D.reshape(-1, D.shape[-1])


def generic_point(chain: Chain) -> FloatArray:
    """A tool shift (in the end frame) that puts the measured point off every joint axis: the
    structure of positions-only data is that of a point in general position. A point that
    lies on the last axis (a target at the flange's centre) hides that joint's offset; the
    data's own rank then says so."""
    return np.array([0.31, 0.23, 0.17]) * reach(chain)


def alike(
    A: FloatArray, c: FloatArray, names: Sequence[int], terms: int = 3, rtol: float = 1e-6
) -> tuple[int, ...]:
    """The few columns of ``A`` (unit norm) that ``c`` is a combination of, by orthogonal
    matching pursuit: up to ``terms`` columns, as many as it takes to explain ``c`` to ``rtol``
    of its norm (all ``terms`` if none does); ``names[j]`` names column ``j``."""
    picked: list[int] = []
    r = c.copy()
    for _ in range(terms):
        j = int(np.argmax(np.abs(A.T @ r)))
        if j in picked:
            break
        picked.append(j)
        coef = np.linalg.lstsq(A[:, picked], c, rcond=None)[0]
        r = c - A[:, picked] @ coef
        if np.linalg.norm(r) < rtol * np.linalg.norm(c):
            break
    return tuple(names[j] for j in picked)


def reach(chain: Chain) -> float:
    """A length that turns angles into comparable lengths (m per rad): the farthest joint point
    or end frame from the base, at least 0.1 m."""
    _, points = joint_lines(chain)
    far = max([float(np.linalg.norm(chain.home[:3, 3])), *np.linalg.norm(points, axis=1)])
    return float(max(far, 0.1))


def _direction(v: FloatArray) -> str:
    """A unit direction in the robot's base frame at ``q = 0``: ``"the base's -z"`` along an axis
    (to 1e-9), else ``"[0.707, 0, -0.707] in the base"``."""
    k = int(np.argmax(np.abs(v)))
    if abs(v[k]) > 1.0 - 1e-9:
        return f"the base's {'-' if v[k] < 0 else ''}{_AXES[k]}"
    return "[" + ", ".join(f"{round(float(x), 3) + 0.0:.3g}" for x in v) + "] in the base"


def words(model: CalibrationModel, keys: Sequence[int]) -> str:
    """``"a, b and c"`` for the parameters ``keys``."""
    items = [model.params[k].words for k in keys]
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def as_chain(model: Chain | str | os.PathLike[str] | LoadedModel, frame: str | None) -> Chain:
    """``model`` if it is a chain, else :func:`poekin.load` of it (with ``frame``).

    Raises:
        InputError: ``model`` is none of those (None, an array...), or a chain with a
            ``frame`` other than its own (a chain's end frame is chosen when it is loaded).
    """
    if isinstance(model, Chain):
        if frame is not None and frame != model.frame:
            raise InputError(
                f"frame={frame!r}, but the chain given ends at {model.frame!r}: a chain's end "
                f"frame is chosen when it is loaded: poekin.load(source, {frame!r}), or drop frame"
            )
        return model
    from poekin.io.loading import load
    from poekin.io.sources import LoadedModel

    if not isinstance(model, str | os.PathLike | LoadedModel):
        raise InputError(
            f"model must be a Chain, or what poekin.load takes (a Menagerie name, an MJCF or URDF "
            f"path), got {type(model).__name__}"
        )
    return load(model, frame)


@functools.lru_cache(maxsize=16)
def model_of(chain: Chain, measure: Measure) -> CalibrationModel:
    """The calibration model of ``chain`` (its structure analysed once per chain)."""
    return CalibrationModel.of(chain, measure)
