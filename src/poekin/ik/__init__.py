"""Inverse kinematics: which joint values put a chain's end frame at a target pose.

* :meth:`poekin.Chain.ik` and :meth:`poekin.Tree.ik`: numerical IK for every chain and every
  arm or leg of a tree, batched, inside the joint limits, the same bits everywhere
  (:mod:`poekin.ik.numerical`: the algorithm, its NumPy reference and the compiled kernel's
  dispatch; :mod:`poekin.ik.fixed`: the traceable solve of JAX arrays and PyTorch
  tensors and its implicit derivative; :mod:`poekin.ik.trees`); the answer is an
  :class:`IKResult`.
* :mod:`poekin.ik._rng`: the counter-based random starts; :mod:`poekin.ik._angles`: revolute
  angles brought into the joint limits by whole turns, shared by every solver.
"""

from poekin.ik.numerical import IKResult

__all__ = ["IKResult"]
