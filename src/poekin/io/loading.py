"""``poekin.load`` and ``poekin.load_tree``: one entry point for Menagerie names, MJCF and URDF.

MJCF models and Menagerie robots are compiled by MuJoCo (:mod:`poekin.io.sources`) and read from
the compiled model (:mod:`poekin.io.import_mujoco`). A ``.urdf`` path is read by
:mod:`poekin.io.import_urdf`, without meshes.
"""

from __future__ import annotations

import os
import pathlib

from numpy.typing import ArrayLike

from poekin.chain import Chain, rigid_transform
from poekin.errors import InputError, UnknownFrameError, did_you_mean
from poekin.io.import_mujoco import tree_from_model
from poekin.io.sources import LoadedModel, load_model
from poekin.tree import Tree

__all__ = ["default_frame", "is_urdf", "load", "load_tree"]

Source = str | os.PathLike[str] | LoadedModel


def _path(source: Source) -> pathlib.Path:
    return source.xml_path if isinstance(source, LoadedModel) else pathlib.Path(source)


def is_urdf(source: Source) -> bool:
    """Whether ``source`` is a URDF file (by its ``.urdf`` suffix)."""
    return _path(source).suffix.lower() == ".urdf"


def load_tree(
    source: Source, *, floating_base: bool = False, base: ArrayLike | None = None
) -> Tree:
    """Load the whole kinematic tree of a Menagerie robot, an MJCF file or a URDF file.

    Args:
        source: e.g. ``"unitree_go2"`` (resolved by ``mujoco_menagerie``, which honours
            ``MENAGERIE_ROOT``), a path to an MJCF or ``.urdf`` file, or a loaded model.
        floating_base: URDF only: give the root link a free joint named ``floating_base``
            (``qpos`` then starts with ``x y z qw qx qy qz``). An MJCF model says so itself
            with ``<freejoint/>``.
        base: ``T_world_base``, where the model's world frame sits in yours (a ``(4, 4)``
            rigid transform or ``x y z qw qx qy qz``): :meth:`Tree.with_base`. A model with a
            free joint is placed by its ``qpos`` instead (an :class:`InputError`).

    Example:
        >>> tree = poekin.load_tree("unitree_go2")  # free base + 12 hinges
        >>> tree.fk(tree.qpos0).shape               # every body and site
        (14, 4, 4)
    """
    if base is not None:
        rigid_transform(base, "base")  # a bad base is said before the model is read
    if is_urdf(source):
        from poekin.io.import_urdf import tree_from_urdf

        tree = tree_from_urdf(_path(source), floating_base=floating_base)
    elif floating_base:
        raise InputError(
            "floating_base applies to URDF; an MJCF model declares a free base itself "
            "(<freejoint/> in the root body)"
        )
    else:
        loaded = source if isinstance(source, LoadedModel) else load_model(source)
        tree = tree_from_model(
            loaded.model,
            robot=loaded.robot,
            unknown_masses=loaded.unknown_masses,
            source_file=str(loaded.xml_path),
        )
    return tree if base is None else tree.with_base(base)


def default_frame(tree: Tree) -> str:
    """The end frame when none is named: the model's only site, or, in a model without sites
    (a URDF), its only leaf body.

    Raises:
        UnknownFrameError: several sites, or no site and several leaf bodies; the message lists
            the candidates.
    """
    if tree.site_names:
        if len(tree.site_names) == 1:
            return tree.site_names[0]
        raise UnknownFrameError(
            f"the model has {len(tree.site_names)} sites, so name the end frame with --frame / "
            f"frame=: {did_you_mean('', [*tree.site_names, *tree.body_names])}"
        )
    parents = set(tree.body_parents.tolist())
    leaves = [b for k, b in enumerate(tree.body_names) if k not in parents]
    if len(leaves) == 1:
        return leaves[0]
    raise UnknownFrameError(
        f"the model has no site and {len(leaves)} end links, so name the end frame with "
        f"--frame / frame=: {did_you_mean('', leaves)}"
    )


def load(
    source: Source,
    frame: str | None = None,
    *,
    base: ArrayLike | None = None,
    tool: ArrayLike | None = None,
) -> Chain:
    """Load a PoE chain from a Menagerie robot name, an MJCF path or a URDF path.

    Args:
        source: e.g. ``"universal_robots_ur5e"``, a path to an MJCF or ``.urdf`` file, or an
            already loaded model.
        frame: the end frame, a site or body (URDF: link) name; None means the model's only
            site, or in a model without sites (URDF) its only leaf body.
        base: ``T_world_base``, where the robot's base (the model's world frame) sits in your
            world: a ``(4, 4)`` rigid transform or ``x y z qw qx qy qz``
            (:meth:`Chain.with_base`).
        tool: ``T_flange_tool``, a tool on ``frame``, given in that frame, as ``base`` is
            (:meth:`Chain.with_tool`): the chain's end frame is then ``"tool"``.

    Returns:
        The chain of hinge and slide joints from the world to ``frame`` (or to the tool).

    Example:
        >>> chain = poekin.load("universal_robots_ur5e")  # frame: attachment_site
        >>> chain.fk([0.0, -1.57, 1.57, 0.0, 0.0, 0.0]).shape
        (4, 4)
    """
    placed = {"base": base, "tool": tool}
    for name, T in placed.items():
        if T is not None:
            placed[name] = rigid_transform(T, name)  # said before the model is read
    tree = load_tree(source)
    chain = tree.chain(frame if frame is not None else default_frame(tree))
    if placed["base"] is not None:
        chain = chain.with_base(placed["base"])
    return chain if placed["tool"] is None else chain.with_tool(placed["tool"])
