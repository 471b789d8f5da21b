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

"""The serialized trajectory the node publishes is the JointTrajectory message, field by field."""

from builtin_interfaces.msg import Time
from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.conversions import joint_trajectory_data
from ellipath_ros.conversions import joint_trajectory_message
from ellipath_ros.conversions import serialized_joint_trajectory
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.settings import default_values
from ellipath_ros.parameters import build_settings
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from trajectory_msgs.msg import JointTrajectory

SETTINGS = build_settings(default_values())
DATA_FIELDS = ('time_from_start', 'positions', 'velocities', 'accelerations')


def _random_trajectory(rng, count, names):
    times = np.cumsum(rng.uniform(1e-4, 1.7, count)) - rng.uniform(0.0, 1e-4)
    return JointTrajectoryData(names, times, *rng.normal(scale=3.0, size=(3, count, 3)))


def _planned_trajectories(count):
    start = SETTINGS.home_position
    for pick, place in random_pairs(count, seed=11):
        try:
            plan = plan_cycle(start, pick, place, SETTINGS.planner,
                              pick_dwell=SETTINGS.pick_dwell, place_dwell=SETTINGS.place_dwell)
        except EllipathError:
            continue
        start = plan.end_position
        yield plan.joint_trajectory


def _assert_same_message(trajectory, frame_id):
    """Check that the bytes deserialize to joint_trajectory_message's result, stamped too."""
    expected = joint_trajectory_message(trajectory, frame_id, Time())
    serialized = serialized_joint_trajectory(trajectory, frame_id)
    assert deserialize_message(serialized.data, JointTrajectory) == expected
    stamp = Time(sec=1_764_300_000, nanosec=999_999_999)
    expected.header.stamp = stamp
    assert deserialize_message(serialized.stamped(stamp), JointTrajectory) == expected
    # What the node checks is what the bytes hold.
    held = joint_trajectory_data(expected)
    for field in DATA_FIELDS:
        np.testing.assert_array_equal(getattr(serialized.trajectory, field),
                                      getattr(held, field))
    assert serialized.trajectory.joint_names == held.joint_names
    assert serialized.last_time_from_start == expected.points[-1].time_from_start


# Frame ids and joint names of every length modulo 8 put the first point at both alignments.
@pytest.mark.parametrize('frame_id', ['', 'b', 'ab', 'base', 'base_lin', 'world_frame'])
@pytest.mark.parametrize('count', [1, 2, 3, 61])
def test_random_trajectories_serialize_to_the_same_message(frame_id, count):
    rng = np.random.default_rng(count * 31 + len(frame_id))
    for names in (('a', 'b', 'c'), ('arm_0_joint', 'j', 'joint_two')):
        _assert_same_message(_random_trajectory(rng, count, names), frame_id)


def test_planned_trajectories_serialize_to_the_same_message():
    trajectories = list(_planned_trajectories(6))
    assert len(trajectories) >= 4
    for trajectory in trajectories:
        _assert_same_message(trajectory, SETTINGS.frame_id)


def test_times_are_rounded_to_whole_nanoseconds_as_the_message_rounds_them():
    # Half a nanosecond and just below or above it: the same rounding as the message's.
    times = np.array([0.0, 1.0000000005, 1.0000000015, 2.4999999994999, 3.0000000025])
    rng = np.random.default_rng(3)
    trajectory = JointTrajectoryData(('a', 'b', 'c'), times, *rng.normal(size=(3, 5, 3)))
    _assert_same_message(trajectory, 'base')
