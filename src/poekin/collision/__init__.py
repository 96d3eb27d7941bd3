"""Collision: the model's own collision geometry, world obstacles, and distances between them.

* :mod:`~poekin.collision.model`: which geoms are read from the model file (MJCF
  ``contype``/``conaffinity``, URDF ``<collision>``; meshes as their convex hulls) and which
  pairs are checked (MuJoCo's rules);
* :mod:`~poekin.collision.obstacles`: :class:`Box`, :class:`Sphere`, :class:`Capsule`,
  :class:`Plane` and :class:`Mesh`, in the world or attached to a frame;
* :mod:`~poekin.collision.query`: signed distances and witness points, batched over
  configurations (:meth:`poekin.Tree.distances`, :meth:`~poekin.Tree.min_distance`,
  :meth:`~poekin.Tree.in_collision`);
* :mod:`~poekin.collision.primitives` and :mod:`~poekin.collision.gjk`: the distances between
  two convex shapes (closed forms on every array library, GJK and EPA), compiled for NumPy;
* :mod:`~poekin.collision.spheres`: spheres covering each link's geometry, as cuRobo does;
* :mod:`~poekin.collision.avoid`: each pair's distance and its Jacobian, the rows that keep an
  IK solve or a step clear.

Maths only: no file or terminal output here.
"""

from poekin.collision.model import CollisionModel, model_of
from poekin.collision.obstacles import Box, Capsule, Mesh, Obstacle, Plane, Sphere
from poekin.collision.query import Distances, distances, in_collision, min_distance
from poekin.collision.spheres import RobotSpheres, fit_spheres, spheres

__all__ = [
    "Box",
    "Capsule",
    "CollisionModel",
    "Distances",
    "Mesh",
    "Obstacle",
    "Plane",
    "RobotSpheres",
    "Sphere",
    "distances",
    "fit_spheres",
    "in_collision",
    "min_distance",
    "model_of",
    "spheres",
]
