"""poekin: Product-of-Exponentials forward kinematics derived from MuJoCo models.

Conventions: twists and screw axes are ``[w; v]`` (angular first), quaternions ``wxyz``, SI
units, radians. Poses are ``(..., 4, 4)`` homogeneous matrices; joint values ``(..., n)`` mean
exactly what MuJoCo stores in ``qpos``.

>>> import poekin
>>> chain = poekin.load("universal_robots_ur5e")        # screws and M from the model
>>> T_world_ee = chain.fk([0.0, -1.57, 1.57, 0.0, 0.0, 0.0])

``poekin.view`` (the browser viewer, the extra ``view``) and ``poekin.draw`` (the same
scene as a matplotlib figure), and ``poekin.calibrate`` and ``poekin.plan_poses``
(:mod:`poekin.calibration`) are imported when first used, so ``import poekin`` stays fast.
"""

from typing import TYPE_CHECKING, Any

from poekin.chain import Chain, ChainParams, JointType
from poekin.dh import DHTable, dh_from_chain
from poekin.errors import (
    AnalyticIKError,
    HeldFramesError,
    InputError,
    JointLimitsWarning,
    MenagerieUnavailableError,
    MetricsFileError,
    MissingExtraError,
    ModelError,
    PoekinError,
    UnitWarning,
    UnknownFrameError,
    UnknownParamsError,
    UnknownRobotError,
    URDFError,
)
from poekin.io.import_mujoco import chain_from_model, tree_from_model
from poekin.io.import_urdf import URDFLimitsWarning, tree_from_urdf
from poekin.io.loading import load, load_tree
from poekin.io.paramfile import load_params, load_registration
from poekin.io.params import (
    PARAM_SETS,
    UR5_DH,
    UR5E_DH,
    UR5E_HOME,
    UR5E_SCREWS,
    fk_ur5e_poe,
    lynch_park_ur5_chain,
    named_params,
    ur5e_chain,
)
from poekin.io.sources import AssetsStrippedWarning, LoadedModel, MuJoCoWarning, load_model
from poekin.kernel._fast import Form, SlowPathWarning, compiled_kernel, get_threads, set_threads
from poekin.lie import (
    adjoint,
    exp_se3,
    exp_so3,
    hat_se3,
    hat_so3,
    homogeneous,
    inverse,
    log_se3,
    log_so3,
    matrix_exp_se3,
    matrix_exp_so3,
    quat_normalize,
    quat_to_rotation,
    rotation_angle,
    rotation_to_quat,
    rotation_to_rpy,
    vec_to_se3,
    vec_to_so3,
    vee_se3,
    vee_so3,
)
from poekin.tree import Mimic, Tree, TreeJointType, TreeParams
from poekin.verification.diagnose import Diagnosis, diagnose
from poekin.verification.verify import (
    VerifyReport,
    pose_errors,
    sample_joint_values,
    sample_qpos,
    verify,
)

if TYPE_CHECKING:
    from poekin.calibration import calibrate as calibrate
    from poekin.calibration import plan_poses as plan_poses
    from poekin.ik._angles import wrap as wrap
    from poekin.io.exporters import export as export
    from poekin.viewer.app import view as view
    from poekin.viewer.draw import draw as draw

__version__ = "0.1.0"

__all__ = [
    "PARAM_SETS",
    "UR5E_DH",
    "UR5E_HOME",
    "UR5E_SCREWS",
    "UR5_DH",
    "AnalyticIKError",
    "AssetsStrippedWarning",
    "Chain",
    "ChainParams",
    "DHTable",
    "Diagnosis",
    "Form",
    "HeldFramesError",
    "InputError",
    "JointLimitsWarning",
    "JointType",
    "LoadedModel",
    "MenagerieUnavailableError",
    "MetricsFileError",
    "Mimic",
    "MissingExtraError",
    "ModelError",
    "MuJoCoWarning",
    "PoekinError",
    "SlowPathWarning",
    "Tree",
    "TreeJointType",
    "TreeParams",
    "URDFError",
    "URDFLimitsWarning",
    "UnitWarning",
    "UnknownFrameError",
    "UnknownParamsError",
    "UnknownRobotError",
    "VerifyReport",
    "adjoint",
    "chain_from_model",
    "compiled_kernel",
    "dh_from_chain",
    "diagnose",
    "exp_se3",
    "exp_so3",
    "fk_ur5e_poe",
    "get_threads",
    "hat_se3",
    "hat_so3",
    "homogeneous",
    "inverse",
    "load",
    "load_model",
    "load_params",
    "load_registration",
    "load_tree",
    "log_se3",
    "log_so3",
    "lynch_park_ur5_chain",
    "matrix_exp_se3",
    "matrix_exp_so3",
    "named_params",
    "pose_errors",
    "quat_normalize",
    "quat_to_rotation",
    "rotation_angle",
    "rotation_to_quat",
    "rotation_to_rpy",
    "sample_joint_values",
    "sample_qpos",
    "set_threads",
    "tree_from_model",
    "tree_from_urdf",
    "ur5e_chain",
    "vec_to_se3",
    "vec_to_so3",
    "vee_se3",
    "vee_so3",
    "verify",
]


# The names imported at first use, by __getattr__: listed by dir(poekin), not in __all__ (a
# star import would import the viewer, which needs the extra `view`).
_LAZY = ("calibrate", "draw", "export", "plan_poses", "view", "wrap")


def __dir__() -> list[str]:
    """The module's names and the lazily imported ones, so that completion offers them."""
    return sorted({*globals(), *_LAZY})


def __getattr__(name: str) -> Any:
    """``poekin.view`` and ``poekin.draw``, imported at first use (viser, matplotlib),
    ``poekin.calibrate`` and ``poekin.plan_poses`` (:mod:`poekin.calibration`), and
    ``poekin.export`` (:mod:`poekin.io.exporters`), and ``poekin.wrap`` (:mod:`poekin.ik`:
    the model itself imports no solver)."""
    if name == "view":
        from poekin._extras import require_view

        require_view("poekin.view")
        from poekin.viewer.app import view as view

        return view
    if name == "draw":
        from poekin.viewer.draw import draw as draw

        return draw
    if name in ("calibrate", "plan_poses"):
        from poekin import calibration

        return getattr(calibration, name)
    if name == "export":
        from poekin.io.exporters import export as export

        return export
    if name == "wrap":
        from poekin.ik._angles import wrap as wrap

        return wrap
    raise AttributeError(f"module 'poekin' has no attribute {name!r}")
