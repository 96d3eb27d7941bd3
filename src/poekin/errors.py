"""Typed exceptions. Every error poekin raises on purpose derives from :class:`PoekinError`.

Messages are one line: what is wrong, then how to fix it. Lookup errors list the valid names
and suggest the nearest one, so a typo is a one-step fix.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

__all__ = [
    "AnalyticIKError",
    "CalibrationWarning",
    "HeldFramesError",
    "InputError",
    "JointLimitsWarning",
    "MenagerieUnavailableError",
    "MetricsFileError",
    "MissingExtraError",
    "ModelError",
    "PoekinError",
    "URDFError",
    "UnitWarning",
    "UnknownFrameError",
    "UnknownParamsError",
    "UnknownRobotError",
    "did_you_mean",
    "nearest",
]


class PoekinError(Exception):
    """Base class of every error poekin raises on purpose."""


class InputError(PoekinError, ValueError):
    """Numeric input of the wrong shape, type or value (e.g. NaN joint values)."""


class HeldFramesError(InputError):
    """Frames held by a whole-body solve (:meth:`poekin.Tree.ik` with ``hold=``) whose targets
    no configuration within the limits meets together; the message names them."""


class ModelError(PoekinError):
    """A model file is missing, unreadable, malformed, or MuJoCo rejects it."""


class URDFError(ModelError):
    """A URDF file that poekin cannot read as a robot: malformed, or outside what it supports."""


class AnalyticIKError(ModelError):
    """A chain whose joints have no closed-form inverse in :meth:`poekin.Chain.ik_all`: not six
    revolute joints, or axes that fit none of the supported geometries (the message names the
    condition that fails and by how much)."""


class UnknownRobotError(ModelError, LookupError):
    """A Menagerie robot name that the registry does not know."""


class UnknownFrameError(ModelError, LookupError):
    """A site or body name that the model does not have."""


class UnknownParamsError(PoekinError, LookupError):
    """A parameter-set name that :data:`poekin.io.params.PARAM_SETS` does not know."""


class MenagerieUnavailableError(ModelError):
    """A Menagerie robot is known but cannot be fetched (no network, no local clone)."""


class MetricsFileError(PoekinError):
    """A metrics CSV cannot be written safely (bad path, or a header that does not match)."""


def nearest(name: str, valid: Iterable[str], *, cutoff: float = 0.6) -> str | None:
    """The valid name closest to ``name`` (difflib ratio at least ``cutoff``), or None."""
    close = difflib.get_close_matches(name, list(valid), n=1, cutoff=cutoff)
    return close[0] if close else None


def did_you_mean(name: str, valid: Iterable[str], *, listed: int = 12) -> str:
    """Text for an error message: the nearest valid names, then (some of) all valid names.

    >>> did_you_mean("atachment_site", ["attachment_site", "base"])
    "did you mean 'attachment_site'? Valid names: 'attachment_site', 'base'"
    """
    valid = list(valid)
    close = nearest(name, valid)
    hint = f"did you mean {close!r}? " if close else ""
    shown = ", ".join(repr(v) for v in valid[:listed])
    more = f", ... ({len(valid) - listed} more)" if len(valid) > listed else ""
    return f"{hint}Valid names: {shown}{more}" if valid else f"{hint}there are no valid names"


class MissingExtraError(PoekinError, ImportError):
    """An optional feature's library is not installed; the message names the pip command."""


class UnitWarning(UserWarning):
    """Values that look like another unit than the one they are read in (degrees as radians)."""


class JointLimitsWarning(UserWarning):
    """Joint values given as a start (``q0`` of :meth:`poekin.Chain.ik`) lie outside the joint
    limits: the solve starts from them brought into the limits (whole turns, else clamped), so
    a start far outside, such as degrees read as radians, does not keep the answer near it."""


class CalibrationWarning(UserWarning):
    """A calibration's data leave parameters unidentified (too few or too similar poses), or its
    fit did not converge; the message says what to measure."""
