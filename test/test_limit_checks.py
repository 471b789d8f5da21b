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

"""The planner's joint-limit check between the published points, driven by a built input."""

from ellipath_ros.core import planner
from ellipath_ros.core.errors import LimitError
from ellipath_ros.core.joint_trajectory import executed_table
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.planner import plan_transfer
from ellipath_ros.core.planner import PlannerConfig
import numpy as np
import pytest

PICK, PLACE = (0.0, 0.0, -0.8), (0.3, 0.0, -0.75)


def overshooting_points(real_points):
    """
    Wrap ``_joint_points``: publish two points at rest whose quintic breaks the speed limit.

    The points are the leg's own first and last joint positions, at rest, so
    each point is within every joint limit; JTC's quintic between two points at
    rest peaks at 15/8 of the mean speed, here twice the joint speed limit.
    The executed table is the built points' own: only what the planner derives
    from the interpolation between the points can see the overshoot.
    """
    def built(motion, config, bounds, samples=None):
        trajectory, error, _ = real_points(motion, config, bounds, samples)
        ends = trajectory.positions[[0, -1]]
        travel = float(np.abs(ends[1] - ends[0]).max())
        duration = 15.0 / 8.0 * travel / (2.0 * config.joint_limits.max_velocity)
        assert duration < motion.duration
        points = JointTrajectoryData(trajectory.joint_names, np.array([0.0, duration]), ends,
                                     np.zeros((2, 3)), np.zeros((2, 3)))
        built.points = points
        return points, error, executed_table(points, config.geometry)
    return built


def test_joint_speed_between_points_is_checked(monkeypatch):
    config = PlannerConfig()
    limit = config.joint_limits.max_velocity
    built = overshooting_points(planner._joint_points)
    monkeypatch.setattr(planner, '_joint_points', built)
    leg = plan_transfer(PICK, PLACE, config)
    points = built.points
    # The built points are within the limits, their quintic is not (independently: the
    # quintic's speed on a fine grid, at least 1.9 times the limit) ...
    assert np.abs(points.velocities).max() <= limit
    assert np.abs(points.accelerations).max() <= config.joint_limits.max_acceleration
    t = np.linspace(0.0, points.time_from_start[-1], 2001)
    assert np.abs(quintic_interpolate(points, t)[1]).max() >= 1.9 * limit
    # ... so the planner slows them down until the quintic keeps the limit.
    published = leg.joint_trajectory
    assert leg.joint_slowdown >= 1.9
    t = np.linspace(0.0, published.time_from_start[-1], 20001)
    speed, accel = (np.abs(values).max() for values in quintic_interpolate(published, t)[1:])
    assert speed <= limit
    assert accel <= config.joint_limits.max_acceleration
    # Without a slow-down left, the planner refuses it, naming the joint limit the quintic
    # breaks first (its acceleration breaks its limit too, and earlier: whichever comes first).
    monkeypatch.setattr(planner, '_SLOWDOWN_ATTEMPTS', 1)
    with pytest.raises(LimitError, match=r'^joint_\d (velocity|acceleration): expected'):
        plan_transfer(PICK, PLACE, config)
