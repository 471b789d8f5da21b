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

"""Compiled segment checks and moves to whole nanoseconds: the NumPy results, bit for bit."""

import math

from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core.joint_trajectory import _nearest_samples, _sorted_position
from ellipath_ros.core.joint_trajectory import evaluate_segments
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import MotionSamples
from ellipath_ros.core.joint_trajectory import on_whole_nanoseconds
from ellipath_ros.core.joint_trajectory import segment_polynomials
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.knots import segment_deviations
from ellipath_ros.core.planner import plan_transfer
from ellipath_ros.core.planner import PlannerConfig
import numpy as np
import pytest


def test_segment_deviations_are_the_vectorised_distances_bit_for_bit():
    # The check points' forward kinematics is inlined into the compiled segment loop: the
    # same numbers as JTC's quintics evaluated, mapped through forward_kinematics and
    # compared with the planned positions of the samples' table, one array at a time.
    config = PlannerConfig()
    pick, place = random_pairs(6, 3)[5]
    leg = plan_transfer(pick, place, config)
    trajectory = leg.joint_trajectory
    samples = MotionSamples.of(leg.motion, config.geometry)
    times = trajectory.time_from_start
    segments = np.arange(times.size - 1)
    fractions = np.arange(1, 25) / 25.0
    lengths = times[1:] - times[:-1]
    offsets = lengths[:, None] * fractions
    q = evaluate_segments(segment_polynomials(trajectory), offsets, derivatives=False)
    reached = forward_kinematics(q.reshape(-1, 3), config.geometry)
    planned = samples.planned((times[:-1, None] + offsets).ravel())
    difference = reached - planned
    distances = np.sqrt(difference[:, 0] * difference[:, 0] + difference[:, 1] * difference[
        :, 1] + difference[:, 2] * difference[:, 2])
    expected = distances.reshape(-1, fractions.size).max(axis=1)
    got = segment_deviations(samples, trajectory, segments, config.knot_tolerance)
    assert got.tobytes() == expected.tobytes()


def _moved_by_numpy(trajectory):
    """Return the arrays of on_whole_nanoseconds, in its NumPy form (array by array)."""
    times = trajectory.time_from_start
    whole = np.round(times * 1e9)
    whole[-1] = math.ceil(times[-1] * 1e9 - 1e-6)
    whole *= 1e-9
    shift = (whole - times)[:, np.newaxis]
    accelerations = trajectory.accelerations
    segment_jerk = np.diff(accelerations, axis=0) / np.maximum(np.diff(times), 1e-12)[:, None]
    after = np.vstack((segment_jerk, np.zeros((1, 3))))
    before = np.vstack((np.zeros((1, 3)), segment_jerk))
    jerk = np.where(shift > 0.0, after, before)
    velocities = trajectory.velocities
    return (whole,
            trajectory.positions + shift * (velocities + shift * (
                accelerations / 2.0 + shift * jerk / 6.0)),
            velocities + shift * (accelerations + shift * jerk / 2.0),
            accelerations + shift * jerk)


@pytest.mark.parametrize('seed', range(40))
def test_moves_to_whole_nanoseconds_are_the_numpy_arithmetic_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 40))
    # Steps from 1 us (shifts a sizeable share of a segment) to 50 ms, a start at 0 or later.
    times = rng.uniform(0.0, 0.5) * (seed % 2) + np.cumsum(rng.uniform(1e-6, 0.05, count))
    states = [rng.normal(0.0, scale, size=(count, 3)) for scale in (1.0, 3.0, 40.0)]
    trajectory = JointTrajectoryData(('a', 'b', 'c'), times, *states)
    moved = on_whole_nanoseconds(trajectory)
    assert moved is not trajectory
    for got, want in zip((moved.time_from_start, moved.positions, moved.velocities,
                          moved.accelerations), _moved_by_numpy(trajectory)):
        assert got.tobytes() == want.tobytes()


def test_searches_continued_from_a_lower_target_are_numpys():
    # _sorted_position walks from where a lower target's search ended, then bisects; the knot
    # search's nearest samples take it for targets in order and from the start otherwise.
    rng = np.random.default_rng(7)
    for size in (1, 2, 5, 40, 300):
        values = np.sort(rng.choice(rng.uniform(0.0, 1.0, size), size))
        targets = np.concatenate((rng.uniform(-0.1, 1.1, 60), values[::3],
                                  [np.nan, np.inf, -np.inf]))
        for target in targets:
            expected = np.searchsorted(values, target)
            lower = target - rng.uniform(0.0, 0.5) if math.isfinite(target) else -np.inf
            for start in (0, np.searchsorted(values, lower)):
                assert _sorted_position(values, target, start) == expected
        for order in (np.sort(targets), targets):
            low, high = order - 0.01, order + 0.01
            nearest, usable = np.empty(order.size, np.int64), np.empty(order.size, np.bool_)
            _nearest_samples(values, order, low, high, 0.0, nearest, usable)
            # The rule with NumPy's search from the start.
            index = np.minimum(np.maximum(np.searchsorted(values, order), 1), size - 1)
            with np.errstate(invalid='ignore'):
                closer_before = order - values[index - 1] <= values[index] - order
            assert (nearest == np.where(closer_before, index - 1, index)).all()
