"""Seeing the kinematics: the browser viewer (``poekin view``) and the static drawing (``poekin
draw``).

* :mod:`poekin.viewer.scene`: what to draw at a configuration (frames, screw axes, PoE partial
  products, DH frames, the ghost of a parameter set), pure computation on poekin's own FK and
  Jacobians: no viser, no matplotlib;
* :mod:`poekin.viewer.ik`: the IK mode's computation: a target solved from the configuration
  shown, its residual, every closed-form solution as a ghost (no viser);
* :mod:`poekin.viewer.geometry`: the robot's drawable parts (MuJoCo's compiled meshes and
  primitives, URDF meshes through trimesh, or capsule stand-ins between joint anchors);
* :mod:`poekin.viewer.app`: the viser server, its panel and the :class:`~poekin.viewer.app.Viewer`
  handle that :func:`poekin.view` returns (needs the extra ``view``);
* :mod:`poekin.viewer.draw`: the same scene as a matplotlib figure (:func:`poekin.draw`).

Importing this package imports none of them.
"""
