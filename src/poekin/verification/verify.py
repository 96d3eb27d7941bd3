"""Verification of PoE forward kinematics against MuJoCo's ``mj_forward``.

Errors between a reference pose ``T_ref`` (MuJoCo) and a pose ``T`` (PoE):

* position error: ``|p_ref - p|`` in metres;
* orientation error: the geodesic angle of ``R_ref R^T`` in radians, from ``atan2`` (no
  ``arccos``, so it stays accurate near 0 where float-precision agreement lives).
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.chain import Chain
from poekin.dh import DHTable
from poekin.errors import InputError, ModelError, UnknownRobotError
from poekin.io.import_mujoco import FrameKind, find_frame, frame_pose, tree_from_model
from poekin.io.loading import default_frame, is_urdf, load_tree
from poekin.io.sources import LoadedModel, load_model
from poekin.tree import Tree

if TYPE_CHECKING:
    import mujoco

__all__ = [
    "DEFAULT_ORI_TOL",
    "DEFAULT_POS_TOL",
    "VerifyReport",
    "check_sample_memory",
    "mujoco_frame_poses",
    "mujoco_poses",
    "pose_errors",
    "random_generator",
    "sample_joint_values",
    "sample_qpos",
    "verify",
    "whole_number",
]

FloatArray = NDArray[np.float64]
DEFAULT_POS_TOL = 1e-5  # m: the lab's bar, far above float precision (~1e-15 m)
DEFAULT_ORI_TOL = 1e-4  # rad: likewise
# Range sampled for a prismatic joint that has no limits (a revolute one samples [-2 pi, 2 pi]).
UNLIMITED_SLIDE_RANGE = (-1.0, 1.0)


def whole_number(value: object, name: str, minimum: int) -> int:
    """``value`` as an int if it is a whole number >= ``minimum``, else :class:`InputError`."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise InputError(f"{name} must be a whole number, {minimum} or more, got {value!r}")
    return int(value)


def _physical_memory() -> int | None:
    """This machine's memory in bytes, or None where the OS does not say (``sysconf``)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def _bytes(n: float) -> str:
    """``n`` bytes as ``"4.37 TiB"``."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    raise AssertionError("unreachable")


def check_sample_memory(samples: int, floats_per_sample: int) -> None:
    """Refuse, before anything is allocated, ``samples`` configurations whose arrays cannot fit:
    ``floats_per_sample`` float64 values each (a lower bound: what is held at once, e.g. the
    joint values and two poses) more than this machine's memory.

    Raises:
        InputError: naming the memory needed, the machine's, and the most samples that fit.
    """
    total = _physical_memory()
    needed = 8 * samples * floats_per_sample
    if total is None or needed <= total:
        return
    most = total // (8 * floats_per_sample)
    raise InputError(
        f"{samples} samples need at least {_bytes(needed)} of memory for their joint values "
        f"and poses, more than this machine's {_bytes(total)}; use fewer (at most about "
        f"{most:,}), or several runs with different seeds"
    )


def random_generator(seed: int) -> np.random.Generator:
    """NumPy's default generator for ``seed``, a whole number >= 0 (else :class:`InputError`)."""
    return np.random.default_rng(whole_number(seed, "the seed", 0))


def sample_joint_values(
    chain: Chain, n: int, *, seed: int = 0, within_limits: bool = False
) -> FloatArray:
    """``(n, dof)`` joint values, uniform per joint.

    Revolute joints sample ``[-2 pi, 2 pi]`` rad, or their limits with ``within_limits``.
    Prismatic joints sample their limits, or ``[-1, 1]`` m if they have none.

    Raises:
        InputError: ``n`` or ``seed`` is not a whole number >= 0.
    """
    assert chain.limits is not None
    n = whole_number(n, "the number of samples", 0)
    rng = random_generator(seed)
    revolute = np.array([t == "revolute" for t in chain.joint_types], dtype=bool)
    lo, hi = _uniform_ranges(revolute, chain.limits, within_limits)
    return rng.uniform(lo, hi, size=(n, chain.n_joints))


def _uniform_ranges(
    revolute: NDArray[np.bool_], limits: FloatArray, within_limits: bool
) -> tuple[FloatArray, FloatArray]:
    """Per-joint sampling range: see :func:`sample_joint_values`."""
    lo = np.where(revolute, -2 * np.pi, limits[:, 0])
    hi = np.where(revolute, 2 * np.pi, limits[:, 1])
    if within_limits:
        lo = np.where(np.isfinite(limits[:, 0]), limits[:, 0], lo)
        hi = np.where(np.isfinite(limits[:, 1]), limits[:, 1], hi)
    lo = np.where(np.isfinite(lo), lo, UNLIMITED_SLIDE_RANGE[0])
    hi = np.where(np.isfinite(hi), hi, UNLIMITED_SLIDE_RANGE[1])
    return lo, hi


def sample_qpos(tree: Tree, n: int, *, seed: int = 0, within_limits: bool = False) -> FloatArray:
    """``(n, nq)`` random configurations of a whole tree, in MuJoCo's qpos layout.

    Hinge and slide joints as in :func:`sample_joint_values`. A ball joint gets a uniformly
    random unit quaternion; a free joint a position uniform in ``[-1, 1]^3`` m and a uniformly
    random unit quaternion.

    Raises:
        InputError: ``n`` or ``seed`` is not a whole number >= 0.
    """
    n = whole_number(n, "the number of samples", 0)
    rng = random_generator(seed)
    q = np.tile(tree.qpos0, (n, 1))
    for k, kind in enumerate(tree.joint_types):
        a = int(tree.qpos_adr[k])
        if tree.mimics[k] is not None:
            continue
        if kind in ("ball", "free"):
            quat = rng.normal(size=(n, 4))
            quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
            if kind == "free":
                q[:, a : a + 3] = rng.uniform(-1.0, 1.0, size=(n, 3))
                a += 3
            q[:, a : a + 4] = quat
        else:
            lo, hi = _uniform_ranges(
                np.array([kind == "revolute"]), tree.joint_limits[k : k + 1], within_limits
            )
            q[:, a] = rng.uniform(lo[0], hi[0], size=n)
    return q


def pose_errors(T_ref: FloatArray, T: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Position (m) and orientation (rad) errors between ``(..., 4, 4)`` poses."""
    pos = np.linalg.norm(T_ref[..., :3, 3] - T[..., :3, 3], axis=-1)
    ori = lie.rotation_angle(T_ref[..., :3, :3] @ np.swapaxes(T[..., :3, :3], -1, -2))
    return pos, np.asarray(ori, dtype=np.float64)


def mujoco_frame_poses(
    model: mujoco.MjModel,
    qpos: FloatArray,
    frames: Sequence[tuple[FrameKind, int]],
    *,
    progress: bool = False,
) -> FloatArray:
    """``(N, len(frames), 4, 4)`` poses of sites/bodies ``(kind, id)`` from ``mj_forward``,
    for ``qpos`` of shape ``(N, nq)``."""
    import mujoco

    data = mujoco.MjData(model)
    out = np.zeros((len(qpos), len(frames), 4, 4))
    for k in _progress(range(len(qpos)), progress):
        data.qpos[:] = qpos[k]
        mujoco.mj_forward(model, data)
        for f, (kind, fid) in enumerate(frames):
            frame_pose(data, kind, fid, out=out[k, f])
    return out


def _progress(rows: range, progress: bool) -> Iterable[int]:
    """``rows``, with a progress bar if ``progress`` and stderr is a terminal (as tqdm decides
    itself; tqdm is only imported then)."""
    if not (progress and hasattr(sys.stderr, "isatty") and sys.stderr.isatty()):
        return rows
    from tqdm import tqdm

    bar: Iterable[int] = tqdm(rows, desc="mj_forward", unit="q", delay=0.5, leave=False)
    return bar


def mujoco_poses(
    model: mujoco.MjModel, chain: Chain, q: FloatArray, *, progress: bool = False
) -> FloatArray:
    """``(N, 4, 4)`` poses of ``chain.frame`` from ``mj_forward`` for ``q`` of shape ``(N, n)``.

    Joints not in the chain stay at ``qpos0``. ``chain`` must come from ``model``.
    """
    if chain.qpos_indices is None:
        raise ValueError("the chain was not imported from a MuJoCo model")
    kind, fid, _ = find_frame(model, chain.frame)
    qpos = np.tile(model.qpos0, (len(q), 1))
    qpos[:, list(chain.qpos_indices)] = q
    return mujoco_frame_poses(model, qpos, [(kind, fid)], progress=progress)[:, 0]


@dataclasses.dataclass(frozen=True)
class VerifyReport:
    """The outcome of :func:`verify`.

    ``pos_err`` / ``ori_err`` map a method (``"space PoE"``, ``"body PoE"``, ``"DH table"``) to
    ``(N,)`` errors in m / rad (with several frames, the worst frame of each sample). The
    ``max_*`` and ``median_*`` figures are the worst over the methods. ``frame_errors`` maps
    each frame checked to its ``(max position, max orientation)`` error over all methods.
    ``params`` names the parameter set checked (None: the model's own), ``model_file`` and
    ``model_origin`` say which model file it was checked against and where it came from.
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
    frame_errors: Mapping[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    params: str | None = None
    model_file: str = ""
    model_origin: str = ""

    @property
    def sample_range(self) -> str:
        """Where the revolute joint values were drawn, in words."""
        return "within joint limits" if self.within_limits else "in [-2 pi, 2 pi]"

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
            "params": self.params,
            "pos_tol": self.pos_tol,
            "ori_tol": self.ori_tol,
            "sample_range": self.sample_range,
            "methods": self.per_method(),
            "model_file": self.model_file,
            "model_origin": self.model_origin,
            **({"frames": self.per_frame()} if len(self.frame_errors) > 1 else {}),
        }

    def per_frame(self) -> dict[str, dict[str, float]]:
        """``{frame: {max_pos_err_m, max_ori_err_rad}}`` over every method that covers it."""
        return {
            f: {"max_pos_err_m": pos, "max_ori_err_rad": ori}
            for f, (pos, ori) in self.frame_errors.items()
        }

    def per_method(self) -> dict[str, dict[str, float]]:
        """``{method: {max_pos_err_m, median_pos_err_m, max_ori_err_rad, median_ori_err_rad}}``."""
        return {
            m: {
                "max_pos_err_m": float(np.max(self.pos_err[m], initial=0.0)),
                "median_pos_err_m": _median(self.pos_err[m]) if self.samples else 0.0,
                "max_ori_err_rad": float(np.max(self.ori_err[m], initial=0.0)),
                "median_ori_err_rad": _median(self.ori_err[m]) if self.samples else 0.0,
            }
            for m in self.pos_err
        }


def _median(x: FloatArray) -> float:
    """``float(np.median(x))``, to the bit, for ``x`` of shape ``(N,)``, ``N >= 1``, without
    the import of ``numpy.ma`` that ``np.median`` makes."""
    s = np.sort(x)
    n = len(s)
    if math.isnan(s[-1]):  # NaNs sort last
        return math.nan
    return float(s[n // 2] if n % 2 else (s[n // 2 - 1] + s[n // 2]) / 2)


def _model(source: str | os.PathLike[str] | LoadedModel) -> LoadedModel:
    if isinstance(source, LoadedModel):
        return source
    if not isinstance(source, str | os.PathLike):
        raise InputError(
            f"cannot check against a {type(source).__name__}: give the model as a Menagerie robot "
            "name, an MJCF or URDF path, or poekin.load_model(...)"
        )
    return load_model(source)


def _model_of(obj: Chain | Tree | DHTable, against: object) -> LoadedModel:
    """The model that ``obj`` is checked against: ``against``, else the Menagerie robot that
    ``obj.robot`` names (as for ``poekin.load("universal_robots_ur5e")``)."""
    if against is not None:
        return _model(against)  # type: ignore[arg-type]
    kind = type(obj).__name__
    hint = (
        f"to verify a {kind}, say which model to check it against: against= a Menagerie robot "
        "name or a model file's path"
    )
    if not obj.robot or any(c in obj.robot for c in "./\\"):
        raise InputError(f"{hint} ({kind}.robot is {obj.robot!r})")
    try:
        return load_model(obj.robot)
    except UnknownRobotError:
        raise InputError(f"{hint} ({kind}.robot is {obj.robot!r}, not a robot name)") from None


def verify(
    source: str | os.PathLike[str] | LoadedModel | Chain | Tree | DHTable = "universal_robots_ur5e",
    frame: str | None = None,
    *,
    against: str | os.PathLike[str] | LoadedModel | None = None,
    all_frames: bool = False,
    chain: Chain | None = None,
    params: Chain | DHTable | str | None = None,
    samples: int = 1000,
    seed: int = 0,
    within_limits: bool = False,
    pos_tol: float = DEFAULT_POS_TOL,
    ori_tol: float = DEFAULT_ORI_TOL,
    progress: bool = False,
) -> VerifyReport:
    """Compare poekin's FK with ``mj_forward`` on random joint values.

    For one frame reached by hinge and slide joints, the space- and body-form PoE of its chain
    are checked, on random values of the chain's joints (the others stay at ``qpos0``). For a
    frame behind a ball or free joint, and for ``all_frames``, the whole tree is checked on
    random ``qpos`` (:func:`sample_qpos`): ``"tree FK"`` covers every frame, and with
    ``all_frames`` the space and body PoE of every frame that has a chain are checked too.

    Args:
        source: what to check: a model (a Menagerie robot name, an MJCF or URDF path, or a
            :class:`~poekin.io.sources.LoadedModel`), checked against itself; or a
            :class:`Chain`, :class:`Tree` or DH table, checked against ``against`` (default:
            the model its ``robot`` names, as for a chain from ``poekin.load(name)``). A tree
            is checked on all its frames.
        frame: site or body name; None means the model's only site.
        against: the model a chain, tree or table is checked against.
        all_frames: check every body and site in one run (``frame`` must then be None).
        chain: the model's chain, which says which joints move; by default the one derived
            from the model. A chain given here must carry ``qpos_indices``.
        params: the parameters to check, in the model's joint order: a PoE chain (its space and
            body forms are checked), a DH table (the table's own FK and the space and body
            forms of its PoE conversion), or the name or file of one
            (:func:`poekin.load_params`). By default ``chain`` itself.
        samples, seed: how many configurations (1 or more), from which random seed (0 or more).
        within_limits: sample within the joint limits instead of ``[-2 pi, 2 pi]``.
        pos_tol, ori_tol: pass/fail thresholds for the maxima (m, rad).
        progress: show a progress bar on a terminal.

    Raises:
        InputError: bad numbers, a chain or table with no model to check it against, or
            parameters that do not fit the model's chain.
        ModelError: the model cannot be found, read or compiled.
    """
    whole_number(samples, "samples", 1)
    whole_number(seed, "the seed", 0)
    label: str | None = params if isinstance(params, str) else None
    if isinstance(params, str):
        from poekin.io.paramfile import load_params

        params = load_params(params)
    elif params is not None:
        label = params.robot or "your parameters"
    tree: Tree | None = None
    if isinstance(source, Chain) and source.qpos_indices is not None and params is None:
        loaded, chain, frame = _model_of(source, against), source, source.frame
    elif isinstance(source, Chain | DHTable):
        if params is not None:
            raise InputError("give the parameters to check once: as source or as params")
        loaded = _model_of(source, against)
        params, label = source, source.robot or "your parameters"
    elif isinstance(source, Tree):
        loaded, tree, all_frames = _model_of(source, against), source, frame is None
    else:
        if against is not None:
            raise InputError("against= goes with a chain, tree or DH table to check; got a model")
        loaded = _model(source)
    return _verify(
        loaded,
        frame,
        tree=tree,
        all_frames=all_frames,
        chain=chain,
        params=params,
        label=label,
        samples=samples,
        seed=seed,
        within_limits=within_limits,
        pos_tol=pos_tol,
        ori_tol=ori_tol,
        progress=progress,
    )


def _verify(
    loaded: LoadedModel,
    frame: str | None,
    *,
    tree: Tree | None,
    all_frames: bool,
    chain: Chain | None,
    params: Chain | DHTable | None,
    label: str | None,
    samples: int,
    seed: int,
    within_limits: bool,
    pos_tol: float,
    ori_tol: float,
    progress: bool,
) -> VerifyReport:
    model = loaded.model
    urdf = is_urdf(loaded)
    if tree is None:
        tree = load_tree(loaded) if urdf else tree_from_model(model, robot=loaded.robot)
    if all_frames:
        if frame is not None or chain is not None or params is not None:
            raise InputError("all_frames checks the model's own FK: give no frame or parameters")
        names = list(tree.frame_names)
    else:
        names = [frame if frame is not None else default_frame(tree)]
        tree.frame_index(names[0])
    by_chain = not all_frames and not urdf
    by_chain &= chain is not None or params is not None or not _has_ball_or_free(tree, names[0])
    if by_chain:  # one frame reached by hinges and slides: its chain's joints move, as in the lab
        chain = chain or tree.chain(names[0])
        names = [chain.frame]
        # held at once: q, MuJoCo's poses and one FK's
        check_sample_memory(samples, chain.n_joints + 2 * 16)
        q = sample_joint_values(chain, samples, seed=seed, within_limits=within_limits)
        errors = _chain_errors(loaded, chain, params, q, progress)
    elif params is not None:
        raise InputError("--params is checked against MJCF models and Menagerie robots")
    else:  # the whole tree moves: qpos, MuJoCo's and the tree's poses of every frame
        check_sample_memory(samples, tree.nq + 16 * (len(names) + len(tree.frame_names)))
        qpos = sample_qpos(tree, samples, seed=seed, within_limits=within_limits)
        errors = _tree_errors(loaded, tree, names, qpos, progress)
    return VerifyReport(
        robot=loaded.robot,
        frame="all frames" if all_frames else names[0],
        samples=samples,
        seed=seed,
        within_limits=within_limits,
        pos_tol=pos_tol,
        ori_tol=ori_tol,
        pos_err={m: np.max(e[0], axis=1, initial=0.0) for m, e in errors.items()},
        ori_err={m: np.max(e[1], axis=1, initial=0.0) for m, e in errors.items()},
        frame_errors={
            n: (
                max(float(np.max(p[:, f], initial=0.0)) for p, _ in errors.values()),
                max(float(np.max(o[:, f], initial=0.0)) for _, o in errors.values()),
            )
            for f, n in enumerate(names)
        },
        params=label,
        model_file=str(loaded.xml_path),
        model_origin=loaded.origin,
    )


# Per method, ``(N, n_frames)`` position and orientation errors.
_Errors = dict[str, tuple[FloatArray, FloatArray]]


def _tree_errors(
    loaded: LoadedModel, tree: Tree, names: list[str], qpos: FloatArray, progress: bool
) -> _Errors:
    """The tree's FK of ``names`` on ``qpos``, and the space and body PoE of each of those
    frames that has a chain, against ``mj_forward``."""
    model = loaded.model
    full = _mujoco_qpos(tree, model, qpos, loaded)
    mj_ids = [find_frame(model, n)[:2] for n in names]
    T_ref = mujoco_frame_poses(model, full, mj_ids, progress=progress)
    idx = [tree.frame_index(n) for n in names]
    errors = {"tree FK": pose_errors(T_ref, tree.fk(qpos)[:, idx])}
    chains = [(f, tree.chain(n)) for f, n in enumerate(names) if not _has_ball_or_free(tree, n)]
    if chains:
        for method, fk in (("space PoE", Chain.fk), ("body PoE", Chain.fk_body)):
            pos = np.zeros((len(qpos), len(names)))
            ori = np.zeros((len(qpos), len(names)))
            for f, c in chains:
                path = list(tree.full_qpos_adr[list(tree.path_joints(names[f]))])
                pos[:, f], ori[:, f] = pose_errors(T_ref[:, f], fk(c, full[:, path]))
            errors[method] = (pos, ori)
    return errors


def _mujoco_qpos(
    tree: Tree, model: mujoco.MjModel, qpos: FloatArray, loaded: LoadedModel
) -> FloatArray:
    """MuJoCo's ``qpos`` for the tree's ``qpos``: mimic followers get their own entries.

    Raises:
        ModelError: MuJoCo compiled the model with other joints than poekin read.
    """
    import mujoco

    mj_names = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "" for j in range(model.njnt)
    ]
    full = tree.full_qpos(qpos)
    if full.shape[-1] != model.nq or (is_urdf(loaded) and mj_names != list(tree.joint_names)):
        raise ModelError(
            f"MuJoCo compiles {loaded.xml_path.name} with joints {mj_names} but poekin reads "
            f"{list(tree.joint_names)}; the two cannot be compared"
        )
    return full


def _has_ball_or_free(tree: Tree, frame: str) -> bool:
    return any(tree.joint_types[k] in ("ball", "free") for k in tree.path_joints(frame))


def _chain_errors(
    loaded: LoadedModel,
    chain: Chain,
    params: Chain | DHTable | None,
    q: FloatArray,
    progress: bool,
) -> _Errors:
    """One frame's chain on joint values ``q``: the space and body PoE of ``params`` (default:
    the chain), and a DH table's own FK, against ``mj_forward``."""
    checked = chain if params is None else params
    if checked.n_joints != chain.n_joints:
        raise InputError(
            f"the parameters have {checked.n_joints} joints but {loaded.robot}'s chain to "
            f"{chain.frame!r} has {chain.n_joints} ({', '.join(chain.joint_names)})"
        )
    T_ref = mujoco_poses(loaded.model, chain, q, progress=progress)
    errors = {}
    if isinstance(checked, DHTable):
        errors["DH table"] = pose_errors(T_ref, checked.fk(q))
        checked = checked.to_chain()
    errors["space PoE"] = pose_errors(T_ref, checked.fk(q))
    errors["body PoE"] = pose_errors(T_ref, checked.fk_body(q))
    return {m: (pos[:, None], ori[:, None]) for m, (pos, ori) in errors.items()}
