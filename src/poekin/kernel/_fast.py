"""The compiled FK path: models as programs for the C kernel ``poekin.kernel._kernel``, and its
settings.

A program is a list of pose operations, each ``(code, qpos address, parameter offset, slot)``,
and one float64 array of parameters. :func:`chain_program` and :func:`tree_program` write them
from the same constants the pure-NumPy reference path uses (:func:`poekin._poe.poe`,
``poekin._levels.evaluate``), with the same formulas in the same order, so both agree to ~1e-16.

Without the extension (no C compiler at install time) every function here still works:
kernels are None and callers use the NumPy path.
"""

from __future__ import annotations

import copyreg
import dataclasses
import functools
import importlib
import inspect
import os
import warnings
from collections.abc import Callable, Sequence
from typing import Any, Literal, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.errors import InputError, did_you_mean

try:
    from poekin.kernel import _kernel  # type: ignore[attr-defined]
except ImportError:  # built without a C compiler: the NumPy path serves
    _kernel = None

__all__ = [
    "DEFAULT_WIDTH",
    "NUMPY_PATH_SLOWDOWN",
    "Form",
    "KernelWidthWarning",
    "SlowPathWarning",
    "TreeSpec",
    "check_form",
    "compiled_kernel",
    "evaluate",
    "fast_method",
    "get_threads",
    "ik_kernel",
    "kernel_description",
    "result_shape",
    "rigid_targets",
    "run_checked",
    "set_threads",
]

FloatArray = NDArray[np.float64]
Form = Literal["4x4", "3x4", "pos_quat"]
_FORM_SHAPES: dict[str, tuple[int, ...]] = {"4x4": (4, 4), "3x4": (3, 4), "pos_quat": (7,)}

# operation codes, as in _kernel.c
_IDENTITY, _LOAD, _STORE, _CONST, _SCREW, _HINGE, _SLIDE, _BALL, _FREE, _EMIT = range(10)
_AXIS, _AXIS_PITCH = 10, 13  # + 0, 1, 2 for x, y, z
_TRANSLATE, _JCOL, _JEMIT = 16, 17, 18
_JACOBIAN_CODES: dict[str, float] = {"space": 0.0, "body": 1.0, "world": 2.0}


def compiled_kernel() -> bool:
    """Whether the compiled kernel is installed (else FK runs on the pure-NumPy path)."""
    return _kernel is not None


def rigid_targets(T: object) -> bool:
    """Whether ``T`` is a plain float64 ``(..., 4, 4)`` ndarray (C-contiguous, aligned, native
    byte order) of finite rigid transforms by :func:`poekin.ik.numerical.check_targets`'
    tests, decided by the kernel in one pass; False where it is not, or without the kernel
    (the NumPy check then decides, and says why)."""
    return _kernel is not None and bool(_kernel.rigid_targets(T))


#: How much slower the NumPy path is than the kernel on a batch: 63x (UR5e ``chain.fk``) and 39x
#: (go2 ``tree.fk``) against the kernel on one core, twice that against two
#: (docs/performance.md, "Without the compiled kernel").
NUMPY_PATH_SLOWDOWN = "40 to 130 times"
_VECTOR_UNITS = {8: "AVX-512", 4: "AVX2", 2: "SSE2"}
# A batch of at least this many configurations on the NumPy path gets a note, once a process.
_SLOW_NOTE_BATCH = 10_000
_slow_noted = False


class SlowPathWarning(UserWarning):
    """poekin was installed without its compiled kernel, so big batches are slow."""


def kernel_description() -> str:
    """The FK kernel in words: its vector unit and width, or the NumPy path's cost."""
    if _kernel is None:
        return (
            f"no compiled kernel: FK runs on the NumPy path, {NUMPY_PATH_SLOWDOWN} slower in "
            "batches; reinstall poekin with a C compiler"
        )
    width = int(_kernel.get_width())
    return f"compiled FK kernel, {_VECTOR_UNITS[width]}: {width} configurations per vector"


def _note_slow_path(batch: tuple[int, ...]) -> None:
    """Warn once a process when a big batch runs on the NumPy path."""
    global _slow_noted
    if _slow_noted or int(np.prod(batch)) < _SLOW_NOTE_BATCH:
        return
    _slow_noted = True
    warnings.warn(kernel_description(), SlowPathWarning, stacklevel=4)


_Method = TypeVar("_Method", bound=Callable[..., Any])


def fast_method(
    kernel_attr: str, names: tuple[str, ...] | None = None
) -> Callable[[_Method], _Method]:
    """Decorator for a method ``m(self, q, out=None, form="4x4", params=None)`` or
    ``m(self, q, params=None)``: a call ``obj.m(...)`` first runs
    ``getattr(obj, kernel_attr).run(q, out, form)`` in C, and runs the decorated function only
    when that attribute is None, the kernel answers None (arguments to validate, convert or
    refuse, or not NumPy arrays) or ``params`` is given. Without the compiled kernel the
    function is returned as it is.

    With ``names`` (one to three of the method's first parameters), the attribute holds
    ``(fn, *bound)`` once the object knows its default call (None before): a call that gives
    only those parameters runs ``fn(obj, *those, *bound)`` in C (None for one not given), and
    the decorated function where ``fn`` answers None, or for any other argument
    (``Chain.ik(T, q0)``: :func:`poekin.ik.numerical.solve_quick` arms it).

    A Python method around the kernel costs a frame per call: 8-18% of a single UR5e call.
    torch.compile traces Python, not C: it sees the Python ``__get__`` and ``__call__``
    (:func:`_traceable_get`, :func:`_traceable_call`) put in the descriptor's type, and traces
    the decorated function. (Making the descriptor a
    data descriptor, which Dynamo resolves by calling it, cost ~7% of every single call
    instead: CPython does not specialise a data descriptor's method call.)
    """

    def decorate(method: _Method) -> _Method:
        if _kernel is None:
            return method
        given = names
        if given is None:
            given = tuple(n for n in inspect.signature(method).parameters if n != "params")[1:]
        fast = _kernel.FastMethod(kernel_attr, method, given)
        functools.update_wrapper(fast, method)
        return fast  # type: ignore[no-any-return]

    return decorate


def _traceable_get(method: Any, obj: object, owner: type | None = None) -> Any:
    """``FastMethod.__get__`` as Python code sees it, for tools that trace Python only
    (torch.compile): the decorated function bound to ``obj``. (The interpreter uses the C
    descriptor, which binds itself.)"""
    if obj is None:
        return method
    return method.__wrapped__.__get__(obj, owner)


def _traceable_call(method: Any, *args: Any, **kwargs: Any) -> Any:
    """``FastMethod.__call__`` as Python code sees it (``torch.compile(obj.m)`` traces the call
    of the bound C descriptor): the decorated function, called as given."""
    return method.__wrapped__(*args, **kwargs)


def _method_named(module: str, qualname: str) -> Any:
    """The attribute ``qualname`` (``"Chain.fk"``) of ``module``: what a pickled
    :func:`fast_method` stands for."""
    found: Any = importlib.import_module(module)
    for part in qualname.split("."):
        found = getattr(found, part)
    return found


def _reduce_fast_method(method: Any) -> tuple[Callable[..., Any], tuple[str, str]]:
    """Pickle a compiled method descriptor as its class attribute's name, as pickle does a
    function: cloudpickle (Dask, Ray, multiprocessing's spawn) pickles a bound method
    ``chain.fk`` as the function and the chain, and the function is this descriptor."""
    wrapped = method.__wrapped__
    return _method_named, (wrapped.__module__, wrapped.__qualname__)


if _kernel is not None:
    _kernel.expose_python(_traceable_get, _traceable_call)
    copyreg.pickle(_kernel.FastMethod, _reduce_fast_method)


def _default_threads() -> int:
    env = os.environ.get("POEKIN_NUM_THREADS", "")
    if env.strip().isdigit() and int(env) >= 1:
        return int(env)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


_threads = _default_threads()
if _kernel is not None:
    _kernel.set_threads(_threads)


class KernelWidthWarning(UserWarning):
    """``POEKIN_KERNEL_WIDTH`` names a vector width this CPU does not run."""


def _forced_width() -> int:
    """The kernel's vector width (0 without the kernel), from ``POEKIN_KERNEL_WIDTH`` (2 for
    SSE2, 4 for AVX2, 8 for AVX-512; unset or empty: the widest this CPU runs), read once at
    import. Every width gives the same bits; CI runs the kernel's tests again at the narrower
    widths to keep it so."""
    env = os.environ.get("POEKIN_KERNEL_WIDTH", "").strip()
    if _kernel is None:
        return 0
    if not env:
        return int(_kernel.get_width())
    widest = int(_kernel.get_width())
    allowed = [w for w in (2, 4, 8) if w <= widest]
    if env not in {str(w) for w in allowed}:
        warnings.warn(
            f"POEKIN_KERNEL_WIDTH={env!r} is not a width this CPU runs; use one of "
            f"{', '.join(map(str, allowed))} ({', '.join(_VECTOR_UNITS[w] for w in allowed)}), "
            f"or unset it for the widest: running at {widest}",
            KernelWidthWarning,
            stacklevel=2,
        )
        return widest
    return int(_kernel.set_width(int(env)))


#: The kernel's vector width at import (``POEKIN_KERNEL_WIDTH``, else the widest); tests that
#: try other widths come back to it.
DEFAULT_WIDTH = _forced_width()


def set_threads(n: int | None) -> None:
    """Threads for big batches (``None``: the default, every core this process may use).

    Small batches use one thread whatever this says, since starting a thread costs more than
    it saves: under 16,384 configurations for the UR5e, fewer for longer programs (~3,200 for
    the go2's whole tree). The default is read once from the environment variable
    ``POEKIN_NUM_THREADS`` if set, else the number of usable cores.
    """
    global _threads
    if n is None:
        n = _default_threads()
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or not 1 <= n <= 256:
        raise InputError(f"threads must be an integer from 1 to 256 or None, got {n!r}")
    _threads = int(n)
    if _kernel is not None:
        _kernel.set_threads(_threads)


def get_threads() -> int:
    """The thread count :func:`set_threads` set."""
    return _threads


# --- programs -------------------------------------------------------------------------------


class _Program:
    def __init__(self) -> None:
        self.ops: list[tuple[int, int, int, int]] = []
        self.params: list[float] = []
        self.angles = 0

    def op(self, code: int, qadr: int = 0, params: Sequence[Any] = (), slot: int = 0) -> None:
        flat = np.asarray(params, dtype=np.float64).reshape(-1)
        if code in (_SCREW, _HINGE) or _AXIS <= code < _TRANSLATE:  # their slot numbers the angle
            slot, self.angles = self.angles, self.angles + 1
        self.ops.append((code, qadr, len(self.params), slot))
        self.params.extend(flat.tolist())

    def const(self, R: FloatArray, t: FloatArray) -> None:
        """Compose with ``(R, t)``: only ``t`` if ``R`` is exactly I (R I = R in every bit but
        signs of zero), nothing if ``t`` is 0 too."""
        if not np.array_equal(R, np.eye(3)):
            self.op(_CONST, params=[*R.reshape(-1), *t])
        elif np.any(t):
            self.op(_TRANSLATE, params=[*t])

    def kernel(self, nq: int, n_slots: int, n_out: int, frame_axis: bool) -> Any:
        assert _kernel is not None
        ops = np.array(self.ops, dtype=np.int32).reshape(-1, 4)
        params = np.array(self.params or [0.0], dtype=np.float64)
        return _kernel.Kernel(ops, params, nq, n_slots, n_out, frame_axis)


def _hinge(
    p: _Program,
    qadr: int,
    angle: Sequence[float],
    axis: FloatArray,
    point: FloatArray,
    pitch: FloatArray,
    code: int,
    squares: tuple[NDArray[Any], NDArray[Any]] | None = None,
) -> None:
    """A rotation by ``angle = (q scale + offset) - ref`` about ``axis`` through ``point``, then
    ``q pitch`` along it: AXIS about a coordinate axis (see ``lie.coordinate_axis``), else
    ``code`` (SCREW or HINGE, Rodrigues) with ``W = [axis]`` and ``W^2`` (``squares`` if given,
    the same numbers computed for several axes at once)."""
    along = lie.coordinate_axis(axis)
    if along is not None:
        k, sign = along
        a, b = (k + 1) % 3, (k + 2) % 3
        code = (_AXIS if pitch[k] == 0.0 else _AXIS_PITCH) + k
        p.op(code, qadr, [*angle, sign, point[a], point[b], pitch[k]])
        return
    if squares is None:
        W: NDArray[Any] = lie.hat_so3(axis)
        W2: NDArray[Any] = lie.rotate_compose(W, W)
    else:
        W, W2 = squares
    if code == _SCREW:
        p.op(_SCREW, qadr, [*W.reshape(-1), *W2.reshape(-1), *point, *pitch])
    else:
        p.op(_HINGE, qadr, [*angle, *W.reshape(-1), *W2.reshape(-1), *point])


def _chain_joints(
    p: _Program, w: FloatArray, r: FloatArray, u: FloatArray, columns: FloatArray | None
) -> None:
    """Each screw's exponential in turn (``_poe._ScrewTerms``); with ``columns`` (the screws),
    first its Jacobian column ``Ad(cur) S_i``."""
    W = lie.hat_so3(w)  # every joint's [w] and [w]^2 at once (entry by entry, as one at a time)
    W2 = lie.rotate_compose(W, W)
    for i in range(r.shape[0]):
        if columns is not None:
            p.op(_JCOL, params=[*columns[i], 1.0], slot=i)
        _hinge(p, i, (1.0, 0.0, 0.0), w[i], r[i], u[i], _SCREW, (W[i], W2[i]))


def chain_program(
    w: FloatArray,
    r: FloatArray,
    u: FloatArray,
    *,
    left: FloatArray | None,
    right: FloatArray | None,
) -> Any:
    """Kernel for ``left @ exp([S_1] q_1) ... exp([S_n] q_n) @ right`` (see ``_poe.poe``).

    The screws' constants are those of ``_poe._ScrewTerms``; None if not compiled.
    """
    if _kernel is None:
        return None
    p = _Program()
    p.op(_IDENTITY)
    if left is not None:
        p.const(left[:3, :3], left[:3, 3])
    _chain_joints(p, w, r, u, None)
    if right is not None:
        p.const(right[:3, :3], right[:3, 3])
    p.op(_EMIT, slot=0)
    return p.kernel(r.shape[0], 0, 1, frame_axis=False)


def chain_jacobian_program(
    w: FloatArray,
    r: FloatArray,
    u: FloatArray,
    *,
    screws: FloatArray,
    home: FloatArray,
    convention: str,
) -> Any:
    """Kernel for a chain's Jacobian in ``convention`` (see ``_poe.space_jacobian`` and
    ``chain.jacobian_from_world``): before each joint its column ``Ad(T_{i-1}) S_i``, then the
    home pose, then the columns turned into the convention at the end pose. None if not
    compiled, or for a chain without joints (a program with no column is an FK program)."""
    if _kernel is None or r.shape[0] == 0:
        return None
    p = _Program()
    p.op(_IDENTITY)
    _chain_joints(p, w, r, u, screws)
    p.const(home[:3, :3], home[:3, 3])
    p.op(_JEMIT, params=[_JACOBIAN_CODES[convention], r.shape[0]])
    return p.kernel(r.shape[0], 0, 1, frame_axis=False)


@dataclasses.dataclass(frozen=True)
class TreeSpec:
    """A tree's constants as the kernel programs read them (see ``poekin._levels.evaluate``).

    ``slot_of_joint[k]`` is where joint ``k``'s numbers start in the expanded qpos, whose
    entry ``j`` is ``qpos[slots[j]] * slot_scale[j] + slot_offset[j]``.
    """

    nq: int
    body_parents: Sequence[int]
    body_pos: FloatArray
    body_rot: FloatArray
    body_joints: Sequence[Sequence[int]]
    joint_types: Sequence[str]
    joint_axes: FloatArray
    joint_anchors: FloatArray
    joint_refs: FloatArray
    slot_of_joint: Sequence[int]
    slots: Sequence[int]
    slot_scale: Sequence[float]
    slot_offset: Sequence[float]
    site_bodies: Sequence[int]
    site_pos: FloatArray
    site_rot: FloatArray


def _column(p: _Program, dof: int, w: ArrayLike, v: ArrayLike, scale: float = 1.0) -> None:
    p.op(_JCOL, params=[*np.asarray(w, dtype=np.float64), *np.asarray(v), scale], slot=dof)


def _body(
    p: _Program,
    t: TreeSpec,
    b: int,
    columns: tuple[Sequence[int], Sequence[float]] | None = None,
) -> None:
    """Body ``b``'s offset, then its joints; with ``columns = (dof_adr, scale)`` per joint, each
    joint's Jacobian columns too, as MuJoCo's ``cdof``: a hinge's or slide's before it moves,
    a ball's three about the body's axes after it turns, a free joint's three world linear
    columns before it sets the pose and three about the body's axes after."""
    joints = t.body_joints[b]
    if not (joints and t.joint_types[joints[0]] == "free"):  # a free joint sets the pose
        p.const(t.body_rot[b], t.body_pos[b])
    eye = np.eye(3)
    for k in joints:
        j = t.slot_of_joint[k]
        kind, qadr = t.joint_types[k], int(t.slots[j])
        axis, anchor = t.joint_axes[k], t.joint_anchors[k]
        dof, scale = (int(columns[0][k]), float(columns[1][k])) if columns else (0, 1.0)
        if kind == "revolute":
            if columns:
                _column(p, dof, axis, -np.cross(axis, anchor), scale)
            angle = (t.slot_scale[j], t.slot_offset[j], t.joint_refs[k])
            _hinge(p, qadr, angle, axis, anchor, np.zeros(3), _HINGE)
        elif kind == "prismatic":
            if columns:
                _column(p, dof, np.zeros(3), axis, scale)
            p.op(_SLIDE, qadr, [t.slot_scale[j], t.slot_offset[j], t.joint_refs[k], *axis])
        elif kind == "ball":
            p.op(_BALL, qadr, anchor)
            for e in range(3 if columns else 0):
                _column(p, dof + e, eye[e], -np.cross(eye[e], anchor))
        else:
            for e in range(3 if columns else 0):
                _column(p, dof + e, np.zeros(3), eye[e])
            p.op(_FREE, qadr)
            for e in range(3 if columns else 0):
                _column(p, dof + 3 + e, eye[e], np.zeros(3))


def tree_program(t: TreeSpec) -> Any:
    """Kernel for the world poses of every body then every site (see ``poekin._levels.evaluate``);
    None if not compiled."""
    if _kernel is None:
        return None
    nb = len(t.body_parents)
    p = _Program()
    # Each body, then each site, starts from its parent's pose: the state's pose when the
    # parent is the body just done, else a stored one. Only the latter need storing.
    starts = [int(b) for b in t.body_parents] + [int(b) for b in t.site_bodies]
    held = [-2, *range(nb), *([-3] * len(t.site_bodies))][: len(starts)]  # state before each
    loaded = {b for b, h in zip(starts, held, strict=True) if b >= 0 and b != h}
    for b in range(nb):
        _start_from(p, starts[b], held[b])
        _body(p, t, b)
        if b in loaded:
            p.op(_STORE, slot=b)
        p.op(_EMIT, slot=b)
    for s in range(len(t.site_bodies)):
        _start_from(p, starts[nb + s], held[nb + s])
        p.const(t.site_rot[s], t.site_pos[s])
        p.op(_EMIT, slot=nb + s)
    return p.kernel(t.nq, nb, nb + len(t.site_bodies), frame_axis=True)


def _start_from(p: _Program, body: int, held: int) -> None:
    """Make the state ``body``'s pose (the world's for -1), given it holds ``held``'s."""
    if body != held:
        p.op(_IDENTITY) if body < 0 else p.op(_LOAD, slot=body)


def tree_jacobian_program(
    t: TreeSpec,
    frame: int,
    *,
    dof_adr: Sequence[int],
    dof_scale: Sequence[float],
    nv: int,
    convention: str,
) -> Any:
    """Kernel for the Jacobian of frame ``frame`` (bodies, then sites) in ``convention``, in
    qvel's ``nv`` columns (see ``Tree.jacobian``): the bodies from the world to the frame with
    their joints' columns, then the site's offset, then the columns in the convention at the
    frame's pose. ``dof_adr[k]`` is joint ``k``'s first column, ``dof_scale[k]`` 1 or a mimic
    joint's multiplier. None if not compiled, or for a tree without degrees of freedom."""
    if _kernel is None or nv == 0:
        return None
    nb = len(t.body_parents)
    body = frame if frame < nb else int(t.site_bodies[frame - nb])
    path: list[int] = []
    while body >= 0:
        path.append(body)
        body = int(t.body_parents[body])
    p = _Program()
    p.op(_IDENTITY)
    for b in reversed(path):
        _body(p, t, b, (dof_adr, dof_scale))
    if frame >= nb:
        p.const(t.site_rot[frame - nb], t.site_pos[frame - nb])
    p.op(_JEMIT, params=[_JACOBIAN_CODES[convention], nv])
    return p.kernel(t.nq, 0, 1, frame_axis=False)


def ik_kernel(
    jacobian: Any,
    limits: FloatArray,
    revolute: NDArray[np.bool_],
    cyclic: NDArray[np.bool_],
    start_base: FloatArray,
    start_span: FloatArray,
) -> Any:
    """The compiled inverse kinematics solver of a chain (see ``poekin.ik.numerical``): its
    world-Jacobian program ``jacobian`` (:func:`chain_jacobian_program`), ``(n, 2)`` limits,
    which joints are revolute and which of those unlimited (``cyclic``), and the random
    starts' ``base + u span``. None if not compiled."""
    if _kernel is None or jacobian is None:
        return None
    flags = revolute.astype(np.int32) + 2 * cyclic.astype(np.int32)
    return _kernel.IKSolver(jacobian, limits, flags, start_base, start_span)


# --- evaluation -----------------------------------------------------------------------------


def result_shape(batch: tuple[int, ...], frames: tuple[int, ...], form: str) -> tuple[int, ...]:
    """Shape of an FK result: batch axes, then the frame axis (trees), then the form's."""
    return (*batch, *frames, *_FORM_SHAPES[form])


def check_form(form: object) -> Form:
    if not isinstance(form, str) or form not in _FORM_SHAPES:
        raise InputError(f"unknown form {form!r}: {did_you_mean(str(form), list(_FORM_SHAPES))}")
    return form  # type: ignore[return-value]


def _check_out(out: object, shape: tuple[int, ...]) -> None:
    if (
        not isinstance(out, np.ndarray)
        or out.dtype != np.float64
        or out.shape != shape
        or not out.flags.c_contiguous
        or not out.flags.writeable
        or not out.flags.aligned
    ):
        got = (
            f"{out.dtype} array of shape {out.shape}"
            if isinstance(out, np.ndarray)
            else type(out).__name__
        )
        raise InputError(
            f"out must be a writeable C-contiguous float64 array of shape {shape}, got {got}; "
            f"make one with np.empty({shape})"
        )


def reformat(T: FloatArray, form: str) -> FloatArray:
    """``(..., 4, 4)`` poses in ``form``: themselves, the top three rows, or position+quat."""
    if form == "4x4":
        return T
    if form == "3x4":
        return np.ascontiguousarray(T[..., :3, :])
    return np.concatenate([T[..., :3, 3], lie.rotation_to_quat(T[..., :3, :3])], axis=-1)


def evaluate(
    kernel: Any,
    q: ArrayLike,
    out: FloatArray | None,
    form: str,
    validate: Callable[[ArrayLike], FloatArray],
    reference: Callable[[FloatArray], FloatArray],
    frames: tuple[int, ...] = (),
) -> FloatArray:
    """FK of ``q`` with ``out`` and ``form`` once ``kernel.run`` has refused them as they are.

    ``validate`` checks and converts ``q`` (raising InputError), then ``out`` and ``form`` are
    checked here, and the kernel runs on what passed. Without a kernel, ``reference`` is the
    NumPy path (``(..., n) -> (..., *frames, 4, 4)``); ``frames`` is the result's frame axis
    (``()`` for a chain, ``(n_frames,)`` for a tree).
    """
    form = check_form(form)
    arr = np.require(validate(q), dtype=np.float64, requirements=["C", "A"])
    shape = result_shape(arr.shape[:-1], frames, form)
    if out is not None:
        _check_out(out, shape)
    if kernel is None:
        _note_slow_path(arr.shape[:-1])
        result = reformat(reference(arr), form)
        if out is None:
            return result
        out[...] = result
        return out
    done: FloatArray | None = kernel.run(arr, out, form)
    assert done is not None, "validated arguments were refused by the kernel"
    return done


def run_checked(
    kernel: Any,
    x: ArrayLike,
    validate: Callable[[ArrayLike], FloatArray],
    reference: Callable[[FloatArray], FloatArray],
) -> FloatArray:
    """``kernel.run(x)`` if the kernel takes ``x`` as it is; else ``validate(x)`` (which raises
    InputError) run by the kernel, or by ``reference``, the NumPy path, without one."""
    if kernel is not None:
        result: FloatArray | None = kernel.run(x)
        if result is not None:
            return result
    checked = validate(x)
    if kernel is None:
        _note_slow_path(checked.shape[:-1])
        return reference(checked)
    result = kernel.run(np.ascontiguousarray(checked))
    assert result is not None, "validated input was refused by the kernel"
    return result
