"""Whole-body inverse kinematics: many frames at once, a floating base, held contacts.

* :mod:`~poekin.wholebody.tasks`: the targets of a solve, their modes, weights and holds;
* :mod:`~poekin.wholebody.space`: the configuration space (``qpos`` and its tangent);
* :mod:`~poekin.wholebody.qp`: one step, least squares in levels under a box;
* :mod:`~poekin.wholebody.solve`: :meth:`poekin.Tree.ik` with a dict of targets.
"""

from poekin.wholebody.solve import WholeBodyResult, solve

__all__ = ["WholeBodyResult", "solve"]
