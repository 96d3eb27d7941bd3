"""Collision: the model's own collision geometry, world obstacles, and distances between them.

* :mod:`~poekin.collision.model`: which geoms are read from the model file (MJCF
  ``contype``/``conaffinity``, URDF ``<collision>``; meshes as their convex hulls) and which
  pairs are checked (MuJoCo's rules);
* :mod:`~poekin.collision.obstacles`: :class:`Box`, :class:`Sphere`, :class:`Capsule`,
  :class:`Plane` and :class:`Mesh`, in the world or attached to a frame;
* :mod:`~poekin.collision.query`: signed distances and witness points, batched over
  configurations, measured by MuJoCo's ``mj_geomDistance``
  (:meth:`poekin.Tree.distances`, :meth:`~poekin.Tree.min_distance`,
  :meth:`~poekin.Tree.in_collision`).

Maths only: no file or terminal output here.
"""

from poekin.collision.model import CollisionModel, model_of
from poekin.collision.obstacles import Box, Capsule, Mesh, Obstacle, Plane, Sphere
from poekin.collision.query import Distances, distances, in_collision, min_distance

__all__ = [
    "Box",
    "Capsule",
    "CollisionModel",
    "Distances",
    "Mesh",
    "Obstacle",
    "Plane",
    "Sphere",
    "distances",
    "in_collision",
    "min_distance",
    "model_of",
]
