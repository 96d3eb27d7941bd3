"""poekin: Product-of-Exponentials forward kinematics derived from MuJoCo models.

Conventions: twists and screw axes are ``[w; v]`` (angular first), quaternions ``wxyz``, SI
units, radians. Poses are ``(..., 4, 4)`` homogeneous matrices; joint values ``(..., n)`` mean
exactly what MuJoCo stores in ``qpos``.

>>> import poekin
>>> chain = poekin.load("universal_robots_ur5e")        # screws and M from the model
>>> T_world_ee = chain.fk([0.0, -1.57, 1.57, 0.0, 0.0, 0.0])
"""

from poekin._fast import Form, compiled_kernel, get_threads, set_threads
from poekin.chain import Chain, ChainParams, JointType
from poekin.dh import DHTable, dh_from_chain
from poekin.diagnose import Diagnosis, diagnose
from poekin.errors import (
    InputError,
    MenagerieUnavailableError,
    MetricsFileError,
    MissingExtraError,
    ModelError,
    PoekinError,
    UnknownFrameError,
    UnknownParamsError,
    UnknownRobotError,
)
from poekin.import_mujoco import chain_from_model, tree_from_model
from poekin.import_urdf import tree_from_urdf
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
    vec_to_se3,
    vec_to_so3,
    vee_se3,
    vee_so3,
)
from poekin.loading import load, load_tree
from poekin.paramfile import load_params
from poekin.params import (
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
from poekin.sources import AssetsStrippedWarning, LoadedModel, load_model
from poekin.tree import Mimic, Tree, TreeJointType, TreeParams
from poekin.verify import VerifyReport, pose_errors, sample_joint_values, sample_qpos, verify

__version__ = "0.1.0"

__all__ = [
    "PARAM_SETS",
    "UR5E_DH",
    "UR5E_HOME",
    "UR5E_SCREWS",
    "UR5_DH",
    "AssetsStrippedWarning",
    "Chain",
    "ChainParams",
    "DHTable",
    "Diagnosis",
    "Form",
    "InputError",
    "JointType",
    "LoadedModel",
    "MenagerieUnavailableError",
    "MetricsFileError",
    "Mimic",
    "MissingExtraError",
    "ModelError",
    "PoekinError",
    "Tree",
    "TreeJointType",
    "TreeParams",
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
