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

"""The published points sit on whole nanoseconds, moved along the motion, not just rounded."""

import dataclasses
from unittest import mock

from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.conversions import joint_trajectory_data
from ellipath_ros.conversions import joint_trajectory_message
from ellipath_ros.core import planner
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import EXECUTED_KEYS
from ellipath_ros.core.joint_trajectory import executed_peaks
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import on_whole_nanoseconds
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.planner import PlannerConfig
import numpy as np
import pytest
from rclpy.time import Time

CONFIG = PlannerConfig()
START = np.array([0.0, 0.0, -0.8])


def _cubic_jerk_motion(times):
    """Joint states of q = t**3 + 2 t**4 per joint (scaled), exact, at ``times``."""
    scale = np.array([1.0, -0.5, 2.0])
    t = np.asarray(times)[:, None]
    return (scale * (t ** 3 + 2 * t ** 4), scale * (3 * t ** 2 + 8 * t ** 3),
            scale * (6 * t + 24 * t ** 2))


def test_a_moved_point_carries_the_motions_state_at_its_new_time():
    times = np.array([0.0, 1.00000000037e-5, 2.00000000049e-5, 3e-5])
    trajectory = JointTrajectoryData(('a', 'b', 'c'), times, *_cubic_jerk_motion(times))
    moved = on_whole_nanoseconds(trajectory)
    nanoseconds = moved.time_from_start * 1e9
    assert np.all(np.abs(nanoseconds - np.round(nanoseconds)) < 1e-6)
    exact = _cubic_jerk_motion(moved.time_from_start)
    # The step uses the segment's mean jerk: what is left is the jerk's change within 0.5 ns.
    for got, want in zip((moved.positions, moved.velocities, moved.accelerations), exact):
        assert np.abs(got - want).max() <= 1e-12


def test_points_already_on_whole_nanoseconds_are_kept():
    times = np.array([0.0, 1e-3, 2.5e-3])
    trajectory = JointTrajectoryData(('a', 'b', 'c'), times, *_cubic_jerk_motion(times))
    assert on_whole_nanoseconds(trajectory) is trajectory


def _unmoved_cycles(count):
    """Yield (points as planned before the move to whole nanoseconds, the published ones)."""
    start = START
    with mock.patch.object(planner, 'on_whole_nanoseconds', lambda trajectory: trajectory):
        plans = []
        for pick, place in random_pairs(count, seed=5):
            try:
                plan = planner.plan_cycle(start, pick, place, CONFIG, pick_dwell=0.035,
                                          place_dwell=0.035)
            except EllipathError:
                continue
            plans.append(plan.joint_trajectory)
            start = plan.end_position
    for trajectory in plans:
        message = joint_trajectory_message(on_whole_nanoseconds(trajectory), 'base', Time())
        yield trajectory, joint_trajectory_data(message)


CYCLES = list(_unmoved_cycles(8))


@pytest.mark.parametrize('index', range(len(CYCLES)))
def test_the_message_executes_the_planned_points(index):
    planned, received = CYCLES[index]
    nanoseconds = received.time_from_start * 1e9
    assert np.abs(nanoseconds - np.round(nanoseconds)).max() <= 1e-6
    before = executed_peaks(planned, CONFIG.geometry)
    after = executed_peaks(received, CONFIG.geometry)
    for key in EXECUTED_KEYS:
        assert after[key] == pytest.approx(before[key], rel=1e-5)


def test_rounding_the_times_alone_would_break_the_jerk():
    # Why the points are moved: the same points with their times merely rounded (states
    # kept) leave the motion across short segments, and JTC's jerk with them.
    worst = max(
        executed_peaks(dataclasses.replace(planned, time_from_start=np.round(
            planned.time_from_start * 1e9) * 1e-9), CONFIG.geometry)['peak_jerk']
        / executed_peaks(planned, CONFIG.geometry)['peak_jerk'] for planned, _ in CYCLES)
    assert worst > 1.5


def test_the_interpolated_path_is_unchanged_by_the_move():
    planned, received = CYCLES[0]
    times = np.linspace(0.0, planned.time_from_start[-1], 2001)
    moved = quintic_interpolate(received, times)[0]
    assert np.abs(moved - quintic_interpolate(planned, times)[0]).max() <= 1e-9
