# Copyright 2026 The ellipath_ros authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
ROS-free planning core: geometry, timing, kinematics and one orchestration function.

NumPy, numba and Ruckig only. The public API is ``__all__`` below; everything else in
the submodules (and every name with a leading underscore) may change. Most
users need two calls::

    from ellipath_ros.core import plan_cycle, PlannerConfig
    cycle = plan_cycle(start, pick, place, PlannerConfig())
"""

from .errors import (
    DegenerateGeometryError, EllipathError, InvalidInputError, LimitError, UnreachableError)
from .geometry import ARC_POLICIES, ArcPolicy, EllipticArc, PickPlacePath, plan_path
from .joint_trajectory import JointTrajectoryData, TrajectoryRejectedError, validate_jtc
from .kinematics import DeltaGeometry, forward_kinematics, inverse_kinematics, JointLimits
from .limits import CartesianLimits
from .motion import PROFILES, TimedMotion
from .planner import (
    ApproachPlan, CyclePlan, LegPlan, plan_approach, plan_cycle, plan_transfer, PlannerConfig)
from .settings import default_values, Setting, SETTINGS, validate
from .timing import time_motion

__all__ = [
    # Planning a request: the entry points and their configuration and results.
    'plan_cycle',
    'plan_transfer',
    'plan_approach',
    'ApproachPlan',
    'PlannerConfig',
    'CyclePlan',
    'LegPlan',
    # Every setting (name, default, unit, range, description): the one table.
    'SETTINGS',
    'Setting',
    'default_values',
    'validate',
    # The path (Choe et al.'s ellipse between two vertical segments).
    'plan_path',
    'ARC_POLICIES',
    'ArcPolicy',
    'EllipticArc',
    'PickPlacePath',
    # Timing along the path.
    'time_motion',
    'PROFILES',
    'CartesianLimits',
    'TimedMotion',
    # The Delta robot.
    'DeltaGeometry',
    'JointLimits',
    'inverse_kinematics',
    'forward_kinematics',
    # The joint trajectory for ros2_control's joint_trajectory_controller.
    'JointTrajectoryData',
    'validate_jtc',
    # Errors: every one has a machine-readable ``kind``.
    'EllipathError',
    'InvalidInputError',
    'DegenerateGeometryError',
    'UnreachableError',
    'LimitError',
    'TrajectoryRejectedError',
]
