"""The outcome of a calibration: the calibrated chain, and what the data said about it."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.calibration.fit import Fit, Loss
from poekin.calibration.identify import (
    Direction,
    Observability,
    Prediction,
    describe,
    quality_text,
    undetermined,
)
from poekin.calibration.model import CalibrationModel, Measure, State, expected_identifiable, words
from poekin.chain import Chain

__all__ = ["Calibration", "Change"]

FloatArray = NDArray[np.float64]


def _rms(a: FloatArray) -> float:
    return float(np.sqrt(np.mean(a**2))) if a.size else float("nan")


@dataclasses.dataclass(frozen=True)
class Change:
    """One part's calibrated difference from the model, in millimetres and milliradians.

    ``part`` is ``"joint 2 (shoulder_lift_joint)"`` or ``"tool"``; ``joint`` its index (None
    for the tool). For a joint: ``tilt_mrad`` (its axis tilted), ``offset_mm`` (its axis line
    moved: the distance from the model's joint point to the calibrated axis line; 0 for a
    prismatic joint, whose line has no place) and ``encoder`` (its encoder offset, mrad or mm
    for a prismatic joint); for the tool: ``offset_mm`` (its origin moved), ``tilt_mrad`` (it
    turned) and ``encoder`` 0. ``message`` says it in the words ``poekin diagnose`` uses.
    """

    part: str
    joint: int | None
    tilt_mrad: float
    offset_mm: float
    encoder: float
    encoder_unit: str
    message: str


@dataclasses.dataclass(frozen=True, eq=False)
class Calibration:
    """What :func:`poekin.calibrate` found.

    Attributes:
        chain: the calibrated chain: its FK for the encoder readings is the measured frame's
            pose in the measuring frame (joint offsets absorbed into the screws and home).
        nominal: the model's chain it started from.
        model: the corrections and their minimal set (:class:`~.model.CalibrationModel`).
        state: the fitted base and corrections.
        fitted: the fit's details (:class:`~.fit.Fit`): weights, covariance, basis.
        q, measured: the data.
        before, after: per pose, the position (m) and orientation (rad; NaN for positions-only
            data) errors of the model registered to the measuring frame, and of the calibrated
            chain.
        normalised: per pose, the residual in sigmas (RMS over its measured numbers).
        heldout: per pose, its errors when predicted by a fit on the other folds (k-fold), or
            None when there were too few poses to leave any out.
        observability: condition number and O1 (:mod:`~.identify`).
        predicted: how well the calibrated chain predicts poses from its standard errors, at
            the measured configurations and over the workspace (:class:`~.identify.Prediction`).
        unidentified: the combinations of corrections the data cannot determine.
        warnings: what to do about too few or too similar poses.
        source: the model's name or path, for advice.
        prior_m, prior_rad, loss, f_scale, folds: the options used.
    """

    chain: Chain
    nominal: Chain
    model: CalibrationModel
    state: State
    fitted: Fit
    q: FloatArray
    measured: FloatArray
    before: tuple[FloatArray, FloatArray]
    after: tuple[FloatArray, FloatArray]
    normalised: FloatArray
    heldout: tuple[FloatArray, FloatArray] | None
    observability: Observability
    predicted: Prediction
    unidentified: tuple[Direction, ...]
    warnings: tuple[str, ...]
    source: str
    prior_m: float
    prior_rad: float
    loss: Loss
    f_scale: float
    folds: int

    # --- figures ------------------------------------------------------------------------------

    @property
    def measure(self) -> Measure:
        return self.model.measure

    @property
    def poses(self) -> int:
        return len(self.q)

    @property
    def identifiable(self) -> int:
        """The base's 6 and the robot combinations the data identify (standard error within
        one prior unit); weakly determined ones are fitted shrunk toward the model, and listed
        with the unidentified."""
        return 6 + int(self.fitted.identified)

    @property
    def expected_identifiable(self) -> int:
        """``4R + 2P + 6`` (3 fewer for positions only)."""
        return expected_identifiable(self.nominal, self.measure)

    @property
    def condition_number(self) -> float:
        return self.observability.condition_number

    @property
    def residual_rms_m(self) -> float:
        return _rms(self.after[0])

    @property
    def residual_rms_rad(self) -> float | None:
        return _rms(self.after[1]) if self.measure == "pose" else None

    @property
    def heldout_rms_m(self) -> float | None:
        return None if self.heldout is None else _rms(self.heldout[0])

    @property
    def heldout_rms_rad(self) -> float | None:
        if self.heldout is None or self.measure != "pose":
            return None
        return _rms(self.heldout[1])

    @property
    def outliers(self) -> tuple[int, ...]:
        """Poses whose residual exceeds ``f_scale`` sigmas (RMS over their numbers)."""
        return tuple(int(k) for k in np.flatnonzero(self.normalised > self.f_scale))

    @property
    def undetermined(self) -> tuple[int, ...]:
        """The corrections the data do not determine (:func:`~.identify.undetermined`): their
        values are one of several that fit as well."""
        return undetermined(self.model, self.fitted)

    @property
    def base(self) -> FloatArray:
        """``(4, 4)`` ``T_meas_base``: the robot's base frame (the model's world) in the
        measuring frame."""
        return self.state.base

    @property
    def offsets(self) -> FloatArray:
        """``(n,)`` the encoder offsets: the joints stand at ``q + offsets`` (rad, or m)."""
        return self.model.geometry(self.state.x).offsets

    @property
    def robot(self) -> Chain:
        """The calibrated robot in its own base frame: its FK for the encoder readings is the
        measured frame's pose in the robot's base frame (offsets absorbed, as in
        :attr:`chain`), ``chain.fk(q) = base @ robot.fk(q)``. ``poekin calibrate --output``
        writes it, with :attr:`base` as its ``registration``.

        The base frame is the model's, placed where the fit puts it: joint 1's axis line and
        encoder zero are the model's (a measurement from outside cannot tell them from the
        base's own place), so it can differ from where the robot's maker puts its base by that
        joint's small error (a millimetre, a few milliradians)."""
        return self.model.calibrated_chain(dataclasses.replace(self.state, base=np.eye(4)))

    # --- parameters ---------------------------------------------------------------------------

    def _covariance(self) -> dict[int, int]:
        return {k: j for j, k in enumerate(self.model.free)}

    def std(self) -> dict[str, float]:
        """Standard errors of the fitted corrections, ``sigma^2 (J^T J)^-1`` with sigma from
        the residuals (restricted to the identifiable combinations), by key. The base's are
        for its position and small turns about the measuring frame's axes."""
        cov = self.fitted.cov
        var = np.diag(cov).copy()
        R = self.base[:3, :3]
        var[:3] = np.diag(R @ cov[:3, :3] @ R.T)
        var[3:6] = np.diag(R @ cov[3:6, 3:6] @ R.T)
        return {
            self.model.params[k].key: float(np.sqrt(max(var[j], 0.0)))
            for k, j in self._covariance().items()
        }

    def values(self) -> dict[str, float]:
        """Every correction's value by key (m, rad). The base's are its pose in the measuring
        frame: its rotation vector (``base.rx..rz``) and position (``base.x..z``)."""
        x = self.state.x.copy()
        x[:3] = lie.log_so3(self.base[:3, :3])
        x[3:6] = self.base[:3, 3]
        return {p.key: float(v) for p, v in zip(self.model.params, x, strict=True)}

    def parameters(self) -> list[dict[str, Any]]:
        """Every correction: key, words, unit, value, standard error (None unless fitted) and
        status: ``fitted``, ``redundant`` (left out: others move the tool alike, whatever the
        data) or ``unidentified`` (the data cannot tell it from others)."""
        std = self.std()
        redundant = {r.param for r in self.model.redundant}
        unidentified = set(self.undetermined)
        out = []
        for k, (p, value) in enumerate(zip(self.model.params, self.values().values(), strict=True)):
            status = "redundant" if k in redundant else "fitted"
            if k in unidentified:
                status = "unidentified"
            out.append(
                {
                    "key": p.key,
                    "words": p.words,
                    "unit": p.unit,
                    "value": value,
                    "std": std.get(p.key),
                    "status": status,
                }
            )
        return out

    def redundant(self) -> list[dict[str, Any]]:
        """The corrections no data can tell from others, each with those it moves the tool like,
        and a sentence."""
        out = []
        for r in self.model.redundant:
            p = self.model.params[r.param]
            if r.alike:
                alike = words(self.model, r.alike)
                text = (
                    f"{p.words} moves the tool as {alike} {'does' if len(r.alike) == 1 else 'do'}"
                )
            else:
                thing = "point" if self.measure == "position" else "frame"
                text = f"{p.words} does not move the measured {thing}"
            out.append(
                {
                    "parameter": p.key,
                    "alike": [self.model.params[k].key for k in r.alike],
                    "message": f"{text}: kept at or shrunk toward the model's value",
                }
            )
        return out

    # --- changes ------------------------------------------------------------------------------

    def changes(self) -> list[Change]:
        """Each joint's calibrated difference from the model, and the tool's, in mm and mrad.

        In the robot's own base frame as fitted: joint 1's axis is the model's (its place and
        encoder zero cannot be told from the measuring frame's), and so are the other parts the
        fit keeps at the model's values (:meth:`redundant`). The axis tilt and the axis line
        offset are those ``poekin diagnose`` reports
        (:func:`poekin.verification.diagnose.joint_differences`).
        """
        from poekin.verification.diagnose import joint_differences

        robot, nominal = self.model.robot_chain(self.state.x), self.nominal  # offsets apart
        tilt, offset = joint_differences(robot, nominal)
        partial = {self.model.params[k].joint for k in self.undetermined}
        fitted = {self.model.params[k].joint for k in self.model.free}
        out = []
        for i, name in enumerate(nominal.joint_names):
            part = f"joint {i + 1} ({name})"
            revolute = nominal.joint_types[i] == "revolute"
            unit = "mrad" if revolute else "mm"
            enc = float(self.offsets[i]) * 1e3
            items = [f"axis tilted by {tilt[i] * 1e3:.3g} mrad"]
            if revolute:
                items.append(f"axis line offset by {offset[i] * 1e3:.3g} mm")
            items.append(f"encoder offset {enc:+.3g} {unit}")
            if i in partial:
                items.append("not all identified (other values fit as well)")
            if i not in fitted:  # joint 1: nothing of it is fitted, the base takes it
                items = ["its axis and encoder zero are the base's (no data tell them apart)"]
            out.append(
                Change(
                    part,
                    i,
                    tilt[i] * 1e3,
                    offset[i] * 1e3,
                    enc,
                    unit,
                    f"{part}: {', '.join(items)}",
                )
            )
        dp = float(np.linalg.norm(robot.home[:3, 3] - nominal.home[:3, 3])) * 1e3
        turn = float(lie.rotation_angle(nominal.home[:3, :3].T @ robot.home[:3, :3])) * 1e3
        text = f"tool: its origin moved by {dp:.3g} mm"
        if self.measure == "pose":
            text += f", turned by {turn:.3g} mrad"
        else:
            turn = float("nan")
        if None in partial:
            text += ", not all identified (other values fit as well)"
        out.append(Change("tool", None, turn, dp, 0.0, "", text))
        return out

    def _std_line(self) -> str:
        """The largest standard error of each kind of correction, in mm and mrad."""
        std = self.std()
        kinds = (
            ("encoder offsets", "offset"),
            ("axis tilts", "tilt"),
            ("axis shifts", "shift"),
            ("tool", "tool"),
            ("base", "base"),
        )
        parts = []
        for label, group in kinds:
            by_unit: dict[str, float] = {}
            for p in self.model.params:
                if p.group == group and p.key in std:
                    by_unit[p.unit] = max(by_unit.get(p.unit, 0.0), std[p.key])
            if by_unit:
                values = [
                    f"{by_unit[u] * 1e3:.2g} {'mm' if u == 'm' else 'mrad'}"
                    for u in ("m", "rad")
                    if u in by_unit
                ]
                parts.append(f"{label} {', '.join(values)}")
        return "; ".join(parts)

    # --- output ------------------------------------------------------------------------------

    def summary(self) -> dict[str, Any]:
        """The JSON object ``poekin calibrate --json`` prints."""

        def num(x: float | None) -> float | None:
            return None if x is None or not np.isfinite(x) else float(x)

        hp = None if self.heldout is None else self.heldout[0]
        return {
            "robot": self.nominal.robot,
            "frame": self.nominal.frame,
            "measure": self.measure,
            "poses": self.poses,
            "identifiable": self.identifiable,
            "expected_identifiable": self.expected_identifiable,
            "free_parameters": len(self.model.free),
            "condition_number": num(self.condition_number),
            "observability_o1": num(self.observability.o1),
            "residual_rms_m": self.residual_rms_m,
            "residual_rms_rad": self.residual_rms_rad,
            "residual_max_m": float(np.max(self.after[0])),
            "before_rms_m": _rms(self.before[0]),
            "before_rms_rad": _rms(self.before[1]) if self.measure == "pose" else None,
            "heldout_rms_m": self.heldout_rms_m,
            "heldout_rms_rad": self.heldout_rms_rad,
            "heldout_max_m": None if hp is None else float(np.max(hp)),
            "predicted_rms_m": {
                "measured": self.predicted.measured_m,
                "workspace": self.predicted.workspace_m,
            },
            "predicted_rms_rad": None
            if self.measure != "pose"
            else {
                "measured": self.predicted.measured_rad,
                "workspace": self.predicted.workspace_rad,
            },
            "folds": self.folds if self.heldout is not None else 0,
            "sigma_pos_m": self.fitted.sigma_pos,
            "sigma_ori_rad": num(self.fitted.sigma_ori),
            "loss": self.loss,
            "outliers": list(self.outliers),
            "unidentifiable": [
                {
                    "parameters": [self.model.params[k].key for k in d.params],
                    "std_prior": num(d.std_prior),
                    "message": describe(self.model, d),
                }
                for d in self.unidentified
            ],
            "redundant": self.redundant(),
            "warnings": list(self.warnings),
            "base": self.base.tolist(),
            "offsets": self.offsets.tolist(),
            "parameters": self.parameters(),
            "std": self.std(),
            "changes": [dataclasses.asdict(c) for c in self.changes()],
            "iterations": self.fitted.iterations,
            "converged": self.fitted.converged,
        }

    def report(self) -> list[str]:
        """The text ``poekin calibrate`` prints, one line each."""
        mm = 1e3
        pose = self.measure == "pose"
        n = self.poses

        def errs(pos: FloatArray, ori: FloatArray) -> str:
            text = f"{_rms(pos) * mm:.3g} mm RMS (max {np.max(pos) * mm:.3g} mm)"
            if pose:
                text += f", {_rms(ori) * mm:.3g} mrad RMS (max {np.max(ori) * mm:.3g} mrad)"
            return text

        rows = [("before (the model, registered)", self.before), ("after", self.after)]
        if self.heldout is not None:
            rows.append((f"held out ({self.folds}-fold)", self.heldout))
        width = max(len(label) for label, _ in rows) + 1
        lines = [
            f"{n} {'poses' if pose else 'positions'}; identifiable: {self.identifiable} of "
            f"{self.expected_identifiable} parameters (4R + 2P + 6"
            + ("" if pose else " - 3")
            + f"); {quality_text(self.condition_number, self.observability.o1)}",
            *(f"{label + ':':{width}} {errs(*values)}" for label, values in rows),
        ]
        noise = f"{self.fitted.sigma_pos * mm:.3g} mm"
        if pose:
            noise += f", {self.fitted.sigma_ori * mm:.3g} mrad"
        lines.append(f"noise (sigma, from the residuals unless given): {noise}")
        pr = self.predicted
        at = f"{pr.measured_m * mm:.2g} mm" + (f", {pr.measured_rad * mm:.2g} mrad" if pose else "")
        over = f"{pr.workspace_m * mm:.2g} mm" + (
            f", {pr.workspace_rad * mm:.2g} mrad" if pose else ""
        )
        lines.append(
            f"predicted from the standard errors: {at} RMS at the measured configurations, "
            f"{over} over the workspace (random configurations within the limits)"
            + ("; the unidentified combinations not counted" if self.unidentified else "")
        )
        R, p = self.base[:3, :3], self.base[:3, 3]
        axis = lie.log_so3(R)
        angle = float(np.linalg.norm(axis))
        lines.append(
            f"robot base in the measuring frame: at [{', '.join(f'{v:.4f}' for v in p)}] m, "
            f"turned {np.degrees(angle):.2f} deg about "
            f"[{', '.join(f'{v:+.3f}' for v in axis / max(angle, 1e-300))}]"
        )
        lines.append("changes from the model (mm, mrad):")
        lines += [f"  {c.message}" for c in self.changes()]
        lines.append(f"largest standard errors: {self._std_line()}")
        for d in self.unidentified:
            lines.append(f"unidentified: {describe(self.model, d)}")
        if self.outliers:
            listed = ", ".join(f"{k} ({self.after[0][k] * mm:.3g} mm)" for k in self.outliers[:8])
            lines.append(f"outliers (residual above {self.f_scale:g} sigma): poses {listed}")
        return lines
