"""Motion through time: paths, time scaling, IK along a path, retiming, whole clips.

* :mod:`~poekin.motion.scaling`: time scalings ``s(t)`` (cubic, quintic, trapezoid);
* :mod:`~poekin.motion.paths`: pose paths (screw motion, straight line) and their twists;
* :mod:`~poekin.motion.joint`: joint-space trajectories, between two configurations and through
  via points with blends;
* :mod:`~poekin.motion.retime`: the fastest timing of a joint path within limits;
* :mod:`~poekin.motion.follow`: IK along a pose path, the branch kept (:meth:`poekin.Chain.follow`);
* :mod:`~poekin.motion.track`: a whole clip of targets solved as one problem.

Maths only: no file or terminal I/O here (the CLI, plots and the viewer sit at the edge).
"""

from poekin.motion.follow import FollowResult
from poekin.motion.joint import JointTrajectory, joint_trajectory, via_trajectory
from poekin.motion.paths import line_path, line_path_twist, screw_path, screw_path_twist
from poekin.motion.retime import Retimed, retime
from poekin.motion.scaling import TrapezoidProfile, min_duration, scaling, trapezoid
from poekin.motion.track import TrackResult, track

__all__ = [
    "FollowResult",
    "JointTrajectory",
    "Retimed",
    "TrackResult",
    "TrapezoidProfile",
    "joint_trajectory",
    "line_path",
    "line_path_twist",
    "min_duration",
    "retime",
    "scaling",
    "screw_path",
    "screw_path_twist",
    "track",
    "trapezoid",
    "via_trajectory",
]
