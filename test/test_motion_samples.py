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

"""One sample set per leg: what the knots, the peaks and the slow-downs derive from it."""

import dataclasses

from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.geometry import plan_path
from ellipath_ros.core.joint_trajectory import (
    _distinct_samples, _interval_peaks, _nearest_samples, _NO_BOUNDS, _segments_beyond,
    executed_table, knots_at, MotionSamples, quintic_positions)
from ellipath_ros.core.kinematics import forward_kinematics, inverse_kinematics, joint_motion
from ellipath_ros.core.planner import _slowed_points, plan_transfer, PlannerConfig
from ellipath_ros.core.timing import time_motion
import numpy as np
import pytest

CONFIG = PlannerConfig()
# The paper's profile (on the paper's join): its motion is sampled along its own pieces.
CURVATURE = dataclasses.replace(CONFIG, profile='curvature', join='paper')


def random_pairs(count, seed=11):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield tuple(np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3),
                              rng.uniform(-0.95, -0.7)]) for _ in range(2))


def timed(pick=(0.0, 0.0, -0.8), place=(0.3, 0.0, -0.75), config=CONFIG):
    path = plan_path(pick, place, config.pick_clearance, config.place_clearance, config.arc,
                     config.join, config.join_tolerance)
    return time_motion(path, config.limits, profile=config.profile, r=config.curvature_r)


def test_the_samples_of_a_slowed_motion_are_the_samples_rescaled():
    motion = timed()
    factor = 1.037
    slowed = motion.scaled(factor)
    rescaled = MotionSamples.of(motion, CONFIG.geometry).scaled(factor, slowed)
    # Independently: the slower motion evaluated and converted at the rescaled times.
    position, velocity, acceleration, jerk = slowed.state_at(rescaled.times)
    q, qdot, qddot = joint_motion(position, velocity, acceleration, CONFIG.geometry)
    for mine, exact in ((rescaled.position, position), (rescaled.velocity, velocity),
                        (rescaled.acceleration, acceleration), (rescaled.jerk, jerk),
                        (rescaled.q, q), (rescaled.qdot, qdot), (rescaled.qddot, qddot)):
        np.testing.assert_allclose(mine, exact, rtol=1e-9, atol=1e-9)


def test_slowing_points_down_gives_the_slowed_motions_points_and_peaks():
    leg = plan_transfer((0.0, 0.0, -0.8), (0.3, 0.0, -0.75), CONFIG)
    trajectory = leg.joint_trajectory
    table = executed_table(trajectory, CONFIG.geometry)
    factor = 1.05
    slowed, slowed_table = _slowed_points(trajectory, table, factor)
    # The points are the slower motion's exact joint states at the stretched times ...
    exact = knots_at(leg.motion.scaled(factor), CONFIG.geometry, slowed.time_from_start,
                     CONFIG.joint_names)
    for name in ('positions', 'velocities', 'accelerations'):
        np.testing.assert_allclose(getattr(slowed, name), getattr(exact, name), rtol=1e-9,
                                   atol=1e-9)
    # ... and the scaled peaks are those measured on the slowed points themselves (to the
    # rounding of the jerk's sums, which a segment at nearly constant s'' shows relative to its
    # near-zero jerk: each column is compared on the scale of its largest value too).
    measured = executed_table(slowed, CONFIG.geometry)
    scale = np.abs(measured).max(axis=0)
    np.testing.assert_allclose(slowed_table / scale, measured / scale, rtol=1e-7, atol=1e-8)
    assert slowed_table[:, 2].max() < table[:, 2].max() / factor ** 3 * (1.0 + 1e-9)


def test_planned_joint_peaks_of_the_samples_match_a_dense_grid():
    checked = 0
    for pick, place in random_pairs(12):
        try:
            motion = timed(pick, place)
        except EllipathError:
            continue
        velocity_peak, accel_peak = MotionSamples.of(motion, CONFIG.geometry).joint_peaks()
        t = np.linspace(0.0, motion.duration, int(motion.duration / 2e-5) + 1)
        position, velocity, acceleration, _ = motion.state_at(t)
        _, qdot, qddot = joint_motion(position, velocity, acceleration, CONFIG.geometry)
        # A 20 us grid (5 times finer than the samples) finds at most 0.1 % more.
        assert velocity_peak >= (1.0 - 1e-3) * np.abs(qdot).max()
        assert accel_peak >= (1.0 - 1e-3) * np.abs(qddot).max()
        checked += 1
    assert checked >= 8


def test_segment_peaks_are_the_largest_samples_of_each_interval():
    samples = MotionSamples.of(timed(), CONFIG.geometry)
    times = np.array([0.0, 0.01, 0.0537, 0.12, samples.duration])
    peaks = samples.segment_peaks(times)
    assert peaks.shape == (4, 5)
    for index in range(4):
        inside = (samples.times >= times[index]) & (samples.times <= times[index + 1])
        expected = [np.linalg.norm(samples.velocity[inside], axis=1).max(),
                    np.linalg.norm(samples.acceleration[inside], axis=1).max(),
                    np.linalg.norm(samples.jerk[inside], axis=1).max(),
                    np.abs(samples.qdot[inside]).max(), np.abs(samples.qddot[inside]).max()]
        np.testing.assert_allclose(peaks[index], expected, rtol=1e-12)
    # The compiled loop does what its plain-Python form does.
    interpreted = np.empty_like(peaks)
    _interval_peaks.py_func(*samples._peak_source(), times, interpreted)
    np.testing.assert_array_equal(peaks, interpreted)


def test_segments_beyond_are_those_breaking_a_bound_beyond_the_planned_peak():
    samples = MotionSamples.of(timed(), CONFIG.geometry)
    times = np.linspace(0.0, samples.duration, 40)
    peaks = samples.segment_peaks(times)
    generator = np.random.default_rng(3)
    for _ in range(20):
        # Around the planned peaks and bounds, so that each comparison goes both ways.
        table = peaks * generator.uniform(0.99, 1.01, peaks.shape)
        bounds = peaks.max(axis=0) * generator.uniform(0.5, 1.1, 5)
        expected = np.flatnonzero(((table > bounds) & (table > 1.001 * peaks)).any(axis=1))
        beyond = samples.segments_beyond(times, table, bounds, 1.001)
        np.testing.assert_array_equal(beyond, expected)
        assert 0 < beyond.size < times.size - 1
        np.testing.assert_array_equal(
            _segments_beyond.py_func(*samples._peak_source(), times, table, bounds, 1.001),
            expected)


@pytest.mark.parametrize('config, pairs, least', [(CONFIG, 30, 20), (CURVATURE, 12, 8)])
def test_knots_from_the_samples_meet_the_tolerance_on_random_legs(config, pairs, least):
    checked = 0
    for pick, place in random_pairs(pairs, seed=5):
        try:
            leg = plan_transfer(pick, place, config)
        except EllipathError:
            continue
        trajectory = leg.joint_trajectory
        times = trajectory.time_from_start
        # Each point carries the motion's exact joint position at its time.
        np.testing.assert_allclose(
            trajectory.positions, inverse_kinematics(leg.motion.state_at(times)[0],
                                                     CONFIG.geometry), atol=1e-12)
        # JTC's quintic stays within the tolerance of the plan on a 50 us grid.
        t = np.linspace(0.0, leg.motion.duration, int(leg.motion.duration / 5e-5) + 1)
        executed = forward_kinematics(quintic_positions(trajectory, t), CONFIG.geometry)
        deviation = np.linalg.norm(executed - leg.motion.state_at(t)[0], axis=1).max()
        assert deviation <= CONFIG.knot_tolerance
        assert leg.max_interpolation_error >= 0.95 * deviation
        checked += 1
    assert checked >= least


def test_jerk_steps_are_where_the_path_and_the_law_step():
    motion = timed()
    times, sizes = motion.jerk_steps()
    assert np.all(np.diff(times) > 0.0)
    # T1 and T2 (and the G2 transitions' ends) are among them, found on the law itself.
    ends = motion.path.segment_ends[1:3]
    at_ends = [np.abs(motion.path_state(times)[0] - end).min() for end in ends]
    assert max(at_ends) < 1e-9
    # The sizes are the one-sided jerk differences, evaluated here directly.
    epsilon = 1e-9 * motion.duration
    before = motion.state_at(times - epsilon)[3]
    after = motion.state_at(times + epsilon)[3]
    np.testing.assert_allclose(sizes, np.linalg.norm(after - before, axis=1), rtol=1e-6,
                               atol=1e-6 * CONFIG.limits.max_jerk)


def test_jerk_steps_of_the_curvature_profile_include_the_lines_switches():
    motion = timed(config=CURVATURE)
    times, sizes = motion.jerk_steps()
    # Independently: the TCP jerk on a 1 us grid over the lift (a Ruckig line, straight up)
    # changes by more than a tenth of the limit only across a switch of its profile.
    lift = motion.segment_durations[0]
    t = np.arange(0.0, lift, 1e-6)
    jerk = np.linalg.norm(motion.state_at(t)[3], axis=1)
    switches = t[1:][np.abs(np.diff(jerk)) > 0.1 * CURVATURE.limits.max_jerk]
    assert switches.size >= 2
    found = times[times < lift]
    for switch in switches:
        assert np.abs(found - switch).min() <= 1e-6
    # The sizes are the one-sided jerk differences, evaluated here directly.
    epsilon = 1e-9 * motion.duration
    before, after = (motion.state_at(times + shift)[3] for shift in (-epsilon, epsilon))
    np.testing.assert_allclose(sizes, np.linalg.norm(after - before, axis=1), rtol=1e-6,
                               atol=1e-6 * CURVATURE.limits.max_jerk)


@pytest.mark.parametrize('factor', [1.0, 1.3])
def test_knot_states_move_to_samples_only_inside_their_cell(factor):
    motion = timed().scaled(factor) if factor > 1.0 else timed()
    samples = MotionSamples.of(motion, CONFIG.geometry)
    wanted = np.array([0.0, 0.01234567, 0.1, motion.duration])
    low = np.array([-np.inf, 0.012345, 0.05, 0.2])
    high = np.array([0.005, 0.0123457, 0.15, np.inf])
    times, q, qdot, qddot = samples.states(wanted, low, high)
    # Ends stay where they are; a cell without a sample in its middle half keeps the time.
    assert times[0] == 0.0 and times[-1] == motion.duration
    assert times[1] == wanted[1]
    assert abs(times[2] - wanted[2]) <= 1e-4 * factor and times[2] in samples.times
    exact = knots_at(motion, CONFIG.geometry, times, CONFIG.joint_names)
    for mine, other in ((q, exact.positions), (qdot, exact.velocities),
                        (qddot, exact.accelerations)):
        np.testing.assert_allclose(mine, other, rtol=1e-9, atol=1e-9)


def test_nearest_samples_match_numpy():
    rng = np.random.default_rng(8)
    sample_times = np.sort(np.concatenate((rng.uniform(0.0, 1.0, 300), [0.0, 1.0, 0.5, 0.5])))
    targets = np.sort(rng.uniform(-0.1, 1.1, 80))
    low, high = targets - rng.uniform(0.0, 0.01, 80), targets + rng.uniform(0.0, 0.01, 80)
    index = np.minimum(np.maximum(np.searchsorted(sample_times, targets), 1),
                       sample_times.size - 1)
    expected = np.where(targets - sample_times[index - 1] <= sample_times[index] - targets,
                        index - 1, index)
    moved = sample_times[expected]
    for bounds, usable in (
            ((low, high), (moved - low >= 0.5 * (targets - low))
             & (high - moved >= 0.5 * (high - targets))),
            ((_NO_BOUNDS, _NO_BOUNDS), np.abs(moved - targets) <= 1e-3)):
        nearest, flags = np.empty(80, np.int64), np.empty(80, np.bool_)
        _nearest_samples(sample_times, targets, *bounds, 1e-3, nearest, flags)
        assert (nearest == expected).all()
        assert (flags == usable).all()
        # Some knots may move, some may not: both rules are exercised.
        assert 0 < flags.sum() < 80


def test_planned_table_drops_the_earlier_of_samples_closer_than_the_tolerance():
    rng = np.random.default_rng(4)
    times = np.sort(np.concatenate((rng.uniform(0.0, 1.0, 200), [0.0, 0.0, 0.5, 0.5, 1.0])))
    times[7] = times[6] + 1e-9
    position, velocity = rng.normal(size=(times.size, 3)), rng.normal(size=(times.size, 3))
    for same in (0.0, 1e-8, 2e-3):
        keep = np.append(np.diff(times) > same, True)
        keep[0] = True
        table_times, rows, rates = _distinct_samples(times, position, velocity, same)
        assert np.array_equal(table_times, times[keep])
        assert np.array_equal(rows, position[keep].T) and np.array_equal(rates, velocity[keep].T)
        # Repeats are dropped, and the first and last samples stay.
        assert table_times.size < times.size and table_times[0] == 0.0 and table_times[-1] == 1.0
