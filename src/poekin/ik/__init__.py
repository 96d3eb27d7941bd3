"""Inverse kinematics: which joint values put a chain's end frame at a target pose.

* :meth:`poekin.Chain.ik` and :meth:`poekin.Tree.ik`: numerical IK for every chain, batched,
  inside the joint limits (:mod:`poekin.ik.numerical`, :mod:`poekin.ik.trees`); the result is
  an :class:`IKResult`.

``poekin.ik._angles`` holds what every solver shares: bringing revolute angles into the joint
limits by whole turns.
"""

from poekin.ik.numerical import IKResult

__all__ = ["IKResult"]
