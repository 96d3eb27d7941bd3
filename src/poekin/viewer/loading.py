"""What the viewer and ``poekin draw`` show, from what the user gives: a Menagerie name, an MJCF
or URDF path, a loaded model, a :class:`~poekin.tree.Tree`, or a bare parameter set."""

from __future__ import annotations

import dataclasses
import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

from poekin.chain import Chain
from poekin.dh import DHTable
from poekin.io.sources import LoadedModel
from poekin.tree import Tree
from poekin.viewer.scene import Comparison, Subject, compare, make_subject

__all__ = ["Shown", "keyframes", "load_params_comparison", "load_shown"]


@dataclasses.dataclass(frozen=True, eq=False)
class Shown:
    """A subject and where its geometry comes from: the loaded MuJoCo model (MJCF and
    Menagerie), the URDF file, or neither (a tree or parameter set given as such)."""

    subject: Subject
    loaded: LoadedModel | None = None
    urdf: str | None = None


def keyframes(model: Any) -> dict[str, NDArray[np.float64]]:
    """A compiled MuJoCo model's named keyframes, ``{name: qpos}``."""
    import mujoco

    out = {}
    for k in range(model.nkey):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k)
        if name:
            out[name] = np.array(model.key_qpos[k], dtype=np.float64)
    return out


def load_shown(
    model: Any, frame: str | None = None, *, base: Any = None, tool: Any = None
) -> Shown:
    """The subject for a Menagerie name, an MJCF or URDF path, a loaded model, a tree, a chain
    or a DH table, with ``frame`` as its end frame (None: the default), placed on ``base``
    (``T_world_base``: :meth:`Tree.with_base`, :meth:`Chain.with_base`) with ``tool`` on its
    end frame (``T_frame_tool``), each a ``(4, 4)`` rigid transform or ``x y z qw qx qy qz``.

    Raises:
        PoekinError: an unknown robot or frame, an unreadable file, a base or tool that is no
            rigid transform (said before the model is read), a base for a floating model.
    """
    from poekin.chain import rigid_transform
    from poekin.io.import_mujoco import tree_from_model
    from poekin.io.loading import is_urdf, load_tree
    from poekin.io.sources import load_model

    B = None if base is None else rigid_transform(base, "base")
    T = None if tool is None else rigid_transform(tool, "tool")
    if isinstance(model, (Tree, Chain, DHTable)):
        if B is not None:
            placed = model.to_chain() if isinstance(model, DHTable) else model
            model = placed.with_base(B)
        return Shown(make_subject(model, frame, tool=T))
    if not isinstance(model, LoadedModel) and is_urdf(model):
        return Shown(make_subject(load_tree(model, base=B), frame, tool=T), urdf=os.fspath(model))
    loaded = model if isinstance(model, LoadedModel) else load_model(model)
    tree = tree_from_model(loaded.model, robot=loaded.robot, source_file=str(loaded.xml_path))
    tree = tree if B is None else tree.with_base(B)
    keys = keyframes(loaded.model)
    subject = make_subject(tree, frame, keyframes=keys, name=loaded.robot, tool=T)
    return Shown(subject, loaded=loaded)


def load_params_comparison(
    subject: Subject, params: str | os.PathLike[str] | Chain | DHTable | None
) -> Comparison | None:
    """``params`` (a file, a named set, a chain or a table) diagnosed against the subject."""
    from poekin.io.paramfile import load_params

    if params is None:
        return None
    if isinstance(params, (str, os.PathLike)):
        return compare(subject, load_params(params), os.fspath(params))
    return compare(subject, params)
