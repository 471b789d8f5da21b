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

"""Tests of the JTC-ready joint trajectory: sampling, knots, interpolation, validation."""

from types import SimpleNamespace

from ellipath_ros.core import knots as knot_search
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import LimitError
from ellipath_ros.core.errors import UnreachableError
from ellipath_ros.core.joint_trajectory import check_joint_limits
from ellipath_ros.core.joint_trajectory import DEFAULT_JOINT_NAMES
from ellipath_ros.core.joint_trajectory import executed_table
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import MotionSamples
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.joint_trajectory import sample_joint_trajectory
from ellipath_ros.core.joint_trajectory import TrajectoryRejectedError
from ellipath_ros.core.joint_trajectory import validate_jtc
from ellipath_ros.core.kinematics import DeltaGeometry
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.kinematics import JointLimits
from ellipath_ros.core.knots import _equidistributed
from ellipath_ros.core.knots import _error_weights
from ellipath_ros.core.knots import _weight_sum
from ellipath_ros.core.knots import minimal_knots
import numpy as np
import pytest

GEOMETRY = DeltaGeometry()
NAMES = DEFAULT_JOINT_NAMES


class QuinticLine:
    """Straight line, rest to rest, with the quintic smoothstep timing law."""

    def __init__(self, start, end, duration):
        self.start = np.asarray(start, dtype=float)
        self.end = np.asarray(end, dtype=float)
        self.duration = float(duration)

    def state_at(self, t):
        """Position, velocity, acceleration and jerk at times t (N,)."""
        tau = np.asarray(t, dtype=float)[:, np.newaxis] / self.duration
        span, period = self.end - self.start, self.duration
        s = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau ** 2)
        ds = 30.0 * tau ** 2 * (1.0 - tau) ** 2 / period
        dds = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / period ** 2
        ddds = 60.0 * (1.0 - 6.0 * tau + 6.0 * tau ** 2) / period ** 3
        return self.start + s * span, ds * span, dds * span, ddds * span


class SCurveArc:
    """
    Half-ellipse-like arc in a vertical plane, timed by a jerk-limited S-curve.

    The timing law has piecewise-constant jerk (+J, -J, -J, +J on four quarters), so the TCP
    jerk jumps like a Ruckig profile's: the knot search must refine around the jumps.
    """

    def __init__(self, start, end, lift, duration):
        self.start = np.asarray(start, dtype=float)
        self.end = np.asarray(end, dtype=float)
        self.lift = np.array([0.0, 0.0, lift])
        self.duration = float(duration)
        quarter = self.duration / 4.0
        jerk = 32.0 / self.duration ** 3  # makes s run from 0 to 1
        self.bounds = quarter * np.arange(4)
        self.jerks = np.array([jerk, -jerk, -jerk, jerk])
        s, v, a = [0.0], [0.0], [0.0]
        for j in self.jerks[:3]:
            s.append(s[-1] + v[-1] * quarter + a[-1] * quarter ** 2 / 2 + j * quarter ** 3 / 6)
            v.append(v[-1] + a[-1] * quarter + j * quarter ** 2 / 2)
            a.append(a[-1] + j * quarter)
        self.s0, self.v0, self.a0 = np.array(s), np.array(v), np.array(a)

    def state_at(self, t):
        """Position, velocity, acceleration and jerk at times t (N,)."""
        t = np.asarray(t, dtype=float)
        k = np.clip(np.searchsorted(self.bounds, t, side='right') - 1, 0, 3)
        x, j = t - self.bounds[k], self.jerks[k]
        s = self.s0[k] + self.v0[k] * x + self.a0[k] * x ** 2 / 2 + j * x ** 3 / 6
        ds = self.v0[k] + self.a0[k] * x + j * x ** 2 / 2
        dds = self.a0[k] + j * x
        s, ds, dds, ddds = (value[:, np.newaxis] for value in (s, ds, dds, j))
        half = 0.5 * (self.end - self.start)
        angle = np.pi * s
        cos, sin = np.cos(angle), np.sin(angle)
        path = self.start + half - cos * half + sin * self.lift
        d1 = np.pi * (sin * half + cos * self.lift)
        d2 = np.pi ** 2 * (cos * half - sin * self.lift)
        d3 = np.pi ** 3 * (-sin * half - cos * self.lift)
        return (path, d1 * ds, d2 * ds ** 2 + d1 * dds,
                d3 * ds ** 3 + 3.0 * d2 * ds * dds + d1 * ddds)


LINE = QuinticLine([-0.15, 0.05, -0.8], [0.15, -0.05, -0.75], 0.3)
ARC = SCurveArc([-0.15, 0.05, -0.8], [0.15, -0.05, -0.78], 0.07, 0.3)


def tcp_error(traj, motion, samples):
    """Largest TCP deviation of JTC's interpolation on a uniform grid of samples."""
    times = np.linspace(0.0, motion.duration, samples)
    q = quintic_interpolate(traj, times)[0]
    return np.linalg.norm(forward_kinematics(q, GEOMETRY) - motion.state_at(times)[0],
                          axis=1).max()


def assert_no_knot_can_be_dropped(traj, motion, tolerance):
    """Assert that without any one interior knot JTC's interpolation leaves the tolerance."""
    times = traj.time_from_start
    for drop in range(1, times.size - 1):
        keep = np.arange(times.size) != drop
        thinner = JointTrajectoryData(NAMES, times[keep], traj.positions[keep],
                                      traj.velocities[keep], traj.accelerations[keep])
        assert tcp_error(thinner, motion, 6001) > 0.9 * tolerance


def as_fields(traj, **changes):
    """Copy the trajectory into a plain record (like a converted message), with changes."""
    fields = {name: getattr(traj, name) for name in (
        'joint_names', 'time_from_start', 'positions', 'velocities', 'accelerations')}
    fields.update(changes)
    return SimpleNamespace(**fields)


def test_motions_used_here_are_consistent():
    # Guards the helpers: velocity is the derivative of position, the arc ends at rest.
    for motion in (LINE, ARC):
        times = np.linspace(0.01, 0.29, 15)
        step = 1e-6
        numeric = (motion.state_at(times + step)[0] - motion.state_at(times - step)[0]) / (
            2.0 * step)
        np.testing.assert_allclose(numeric, motion.state_at(times)[1], atol=1e-6)
        end = motion.state_at(np.array([motion.duration]))
        np.testing.assert_allclose(end[0][0], motion.end, atol=1e-12)
        np.testing.assert_allclose(end[1][0], 0.0, atol=1e-12)


def test_quintic_interpolation_reproduces_a_quintic_exactly():
    # JTC's interpolation matches q, q', q'' at both knots, so a degree-5 polynomial
    # sampled at any knots is reproduced exactly in between.
    rng = np.random.default_rng(5)
    coefficients = rng.normal(size=(6, 3))
    powers = np.arange(6)

    def poly(t, order):
        t = np.asarray(t, dtype=float)[:, np.newaxis, np.newaxis]
        factor = np.ones(6)
        for step in range(order):
            factor = factor * np.maximum(powers - step, 0)
        exponent = np.maximum(powers - order, 0)[:, np.newaxis]
        return (factor[:, np.newaxis] * coefficients * t ** exponent).sum(axis=1)

    knots = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0.0, 1.0, 3)]))
    traj = JointTrajectoryData(NAMES, knots, poly(knots, 0), poly(knots, 1), poly(knots, 2))
    times = np.linspace(0.0, 0.999, 301)
    position, velocity, acceleration = quintic_interpolate(traj, times)
    np.testing.assert_allclose(position, poly(times, 0), atol=1e-10)
    np.testing.assert_allclose(velocity, poly(times, 1), atol=1e-9)
    np.testing.assert_allclose(acceleration, poly(times, 2), atol=1e-7)
    # Holding the last point after the end, the first one before the start (unknown state).
    after = quintic_interpolate(traj, [1.0, 2.0])
    np.testing.assert_array_equal(after[0], traj.positions[[-1, -1]])
    np.testing.assert_array_equal(after[1], traj.velocities[[-1, -1]])
    before = quintic_interpolate(traj, -0.5)
    np.testing.assert_array_equal(before[0], traj.positions[0])
    assert before[0].shape == (3,)


def test_sampling_has_a_fixed_period_and_ends_at_the_duration():
    traj = sample_joint_trajectory(ARC, GEOMETRY, 0.007, NAMES)
    times = traj.time_from_start
    assert times[0] == 0.0 and times[-1] == ARC.duration
    np.testing.assert_allclose(np.diff(times[:-1]), 0.007, atol=1e-15)
    assert 0.0 < times[-1] - times[-2] <= 0.007
    assert times.size == 44  # 0 .. 0.301: 43 regular samples below 0.3, plus 0.3
    np.testing.assert_allclose(traj.positions,
                               inverse_kinematics(ARC.state_at(times)[0], GEOMETRY), atol=0.0)
    validate_jtc(traj, expect_names=NAMES)
    exact = sample_joint_trajectory(LINE, GEOMETRY, 0.01)
    assert exact.time_from_start.size == 31  # 0.3 / 0.01 lands on the end: no twin sample
    assert exact.joint_names == NAMES


@pytest.mark.parametrize('motion', [LINE, ARC], ids=['line', 'arc'])
@pytest.mark.parametrize('tolerance', [1e-4, 1e-5])
def test_minimal_knots_stay_within_tolerance(motion, tolerance):
    traj, reported = minimal_knots(motion, GEOMETRY, NAMES, tolerance=tolerance)
    validate_jtc(traj, expect_names=NAMES)
    times = traj.time_from_start
    assert times[0] == 0.0 and times[-1] == motion.duration
    # Knots carry the motion's exact joint states.
    np.testing.assert_allclose(traj.positions,
                               inverse_kinematics(motion.state_at(times)[0], GEOMETRY), atol=0.0)
    # Independent check on a grid ~300 times finer than the search's own.
    verified = tcp_error(traj, motion, 60001)
    assert verified <= tolerance
    assert reported <= 0.95 * tolerance  # the documented margin for peaks between checks
    assert abs(verified - reported) <= 0.02 * verified
    # Few knots: far fewer than a 1 ms sampling, and none can simply be dropped.
    assert times.size <= (7 if tolerance == 1e-4 else 11)
    assert_no_knot_can_be_dropped(traj, motion, tolerance)


def test_minimal_knots_off_the_samples_and_below_the_table_tolerance():
    # Seven samples: most knots are wanted where no sample is near, so the compiled search
    # stops for the motion's states there and runs again; below the planned table's
    # tolerance it also stops for the planned positions at its check points.
    tolerance = 5e-6
    grid = np.linspace(0.0, ARC.duration, 7)
    samples = MotionSamples(ARC, GEOMETRY, grid, ARC.state_at(grid))
    traj, reported = minimal_knots(ARC, GEOMETRY, NAMES, tolerance=tolerance, samples=samples)
    times = traj.time_from_start
    assert times[0] == 0.0 and times[-1] == ARC.duration
    assert not np.isin(times[1:-1], grid).all()  # knots the samples did not give
    np.testing.assert_allclose(traj.positions,
                               inverse_kinematics(ARC.state_at(times)[0], GEOMETRY),
                               rtol=0.0, atol=1e-12)
    assert reported <= 0.95 * tolerance
    assert tcp_error(traj, ARC, 60001) <= tolerance
    # About as few knots as a dense sampling gives (its knots sit on its own samples).
    dense, _ = minimal_knots(ARC, GEOMETRY, NAMES, tolerance=tolerance)
    assert times.size <= dense.time_from_start.size + 2
    assert_no_knot_can_be_dropped(traj, ARC, tolerance)


def test_minimal_knots_evaluate_the_starting_knots_before_the_search(monkeypatch):
    # Four samples 0.1 s apart: every other starting knot (50 ms apart) has no sample near.
    # Their states are evaluated before the compiled search runs, so no run stops for one of
    # them, and the knots are those the search finds when it stops for them itself (below the
    # planned table's tolerance, as above).
    grid = np.linspace(0.0, ARC.duration, 4)
    samples = MotionSamples(ARC, GEOMETRY, grid, ARC.state_at(grid))
    runs = []
    search = knot_search._search_knots

    def recorded(initial, *arguments):
        result = search(initial, *arguments)
        runs.append((initial, result))
        return result

    monkeypatch.setattr(knot_search, '_search_knots', recorded)
    traj, reported = minimal_knots(ARC, GEOMETRY, NAMES, tolerance=5e-6, samples=samples)
    initial = runs[0][0]
    assert initial.size > grid.size
    for _, (status, *_, wanted, _, _, _) in runs:
        assert status != knot_search._NEEDS_STATES or not np.isin(wanted, initial).any()
    # The same knots when the search is handed no starting state and stops for them.
    monkeypatch.setattr(knot_search, '_cells', lambda times: (
        np.full(times.size, -np.inf), np.full(times.size, np.inf)))
    runs.clear()
    unaided, unaided_error = minimal_knots(ARC, GEOMETRY, NAMES, tolerance=5e-6,
                                           samples=samples)
    assert runs[0][1][0] == knot_search._NEEDS_STATES
    assert all(np.array_equal(mine, theirs) for mine, theirs in zip(
        (traj.time_from_start, traj.positions, traj.velocities, traj.accelerations),
        (unaided.time_from_start, unaided.positions, unaided.velocities,
         unaided.accelerations)))
    assert reported == unaided_error


def test_knot_count_estimate_adds_as_numpy_sum():
    rng = np.random.default_rng(3)
    for count in [*range(1, 130), 300]:
        errors = 10.0 ** rng.uniform(-12.0, -3.0, count)
        errors[rng.random(count) < 0.1] = 0.0  # clamped to 1e-300 first
        weights = _error_weights(errors)
        if count <= 128:
            assert _weight_sum(weights) == np.sum(weights)
        else:  # blocks of 128 added in turn, NumPy halves: the same within rounding
            assert abs(_weight_sum(weights) - np.sum(weights)) <= 1e-14 * np.sum(weights)


def test_equidistributed_knots_are_numpys_interpolation():
    rng = np.random.default_rng(5)
    for count in (1, 2, 5, 40):
        for size in (2, 3, 9, 60):
            times = np.concatenate(([0.0], np.cumsum(rng.uniform(1e-4, 0.05, size - 1))))
            errors = 10.0 ** rng.uniform(-10.0, -4.0, size - 1)
            errors[0] = 0.0
            weights = _error_weights(errors)
            cumulative = np.concatenate(([0.0], np.cumsum(weights)))
            expected = np.interp(np.linspace(0.0, cumulative[-1], count + 1), cumulative,
                                 times)
            expected[0], expected[-1] = times[0], times[-1]
            found = _equidistributed(times, weights, count)
            np.testing.assert_array_equal(found, expected)
            assert (np.diff(found) > 0.0).all()


def test_minimal_knots_name_the_unreachable_time():
    too_far = QuinticLine([0.0, 0.0, -0.8], [1.5, 0.0, -0.8], 0.3)
    with pytest.raises(UnreachableError, match=r'^motion at t=0\.[0-9]+ s: TCP position\['):
        minimal_knots(too_far, GEOMETRY)
    with pytest.raises(InvalidInputError, match=r'^tolerance: expected'):
        minimal_knots(LINE, GEOMETRY, NAMES, tolerance=0.0)
    with pytest.raises(InvalidInputError, match=r'^tolerance: expected a tolerance the motion'):
        minimal_knots(LINE, GEOMETRY, NAMES, tolerance=1e-15, min_interval=1e-3)


def test_validate_accepts_a_message_like_record():
    traj = sample_joint_trajectory(LINE, GEOMETRY, 0.05)
    validate_jtc(as_fields(traj, positions=traj.positions.tolist()), expect_names=NAMES)


@pytest.mark.parametrize('change, message', [
    (lambda t: {'time_from_start': np.r_[t.time_from_start[:3], t.time_from_start[2],
                                         t.time_from_start[4:]]},
     r'^time_from_start\[3\]: expected a time > time_from_start\[2\]'),
    (lambda t: {'time_from_start': t.time_from_start[::-1]},
     r'^time_from_start\[0\]|^time_from_start\[1\]'),
    (lambda t: {'time_from_start': np.r_[t.time_from_start[:-1],
                                         t.time_from_start[-2] + 2e-10]},
     r'^time_from_start\[6\]: expected a time at least 1 ns after'),
    (lambda t: {'time_from_start': t.time_from_start - 0.01},
     r'^time_from_start\[0\]: expected a time >= 0'),
    (lambda t: {'positions': t.positions[:, :2]},
     r'^positions: expected shape \(7, 3\)'),
    (lambda t: {'velocities': t.velocities[:-1]},
     r'^velocities: expected shape \(7, 3\)'),
    (lambda t: {'positions': [list(row) for row in t.positions[:-1]] + [[0.1, 0.2]]},
     r'^positions: expected an array'),
    (lambda t: {'accelerations': np.where(np.arange(7)[:, None] == 4, np.nan,
                                          t.accelerations)},
     r'^accelerations\[4\]: expected finite values'),
    (lambda t: {'time_from_start': np.array([])},
     r'^time_from_start: expected shape \(K,\) with K >= 1 points'),
    (lambda t: {'velocities': np.r_[t.velocities[:-1], [[0.0, 1e-6, 0.0]]]},
     r'^velocities\[-1\] of joint_2: expected 0 rad/s at the last point'),
    (lambda t: {'accelerations': np.r_[t.accelerations[:-1], [[0.0, 0.0, -0.5]]]},
     r'^accelerations\[-1\] of joint_3: expected 0 rad/s\^2'),
    (lambda t: {'joint_names': ('joint_1', 'joint_1', 'joint_3')},
     r'^joint_names: expected unique names'),
    (lambda t: {'joint_names': ()}, r'^joint_names: expected 3 names, got none'),
    (lambda t: {'joint_names': ('joint_1', 'joint_2')},
     r'^joint_names: expected 3 names \(one per arm\), got 2'),
    (lambda t: {'joint_names': 'joint_1'}, r'^joint_names: expected a sequence'),
    (lambda t: {'joint_names': ('joint_1', '', 'joint_3')},
     r'^joint_names: expected non-empty strings'),
    (lambda t: {'joint_names': ('joint_2', 'joint_1', 'joint_3')},
     r"^joint_names: expected \('joint_1', 'joint_2', 'joint_3'\)"),
], ids=['repeated time', 'decreasing times', 'sub-nanosecond step', 'negative time',
        'two columns', 'missing row', 'ragged row', 'nan', 'no points', 'final velocity',
        'final acceleration', 'duplicate names', 'no names', 'two names', 'bare string',
        'empty name', 'wrong order'])
def test_validate_rejects_each_malformed_case(change, message):
    traj = sample_joint_trajectory(LINE, GEOMETRY, 0.05)
    assert traj.time_from_start.size == 7
    broken = as_fields(traj, **change(traj))
    with pytest.raises(TrajectoryRejectedError, match=message):
        validate_jtc(broken, expect_names=NAMES)
    assert issubclass(TrajectoryRejectedError, InvalidInputError)


@pytest.mark.parametrize('changes', [
    {'time_from_start': [0.0, 0.1, 0.1]},
    {'positions': np.zeros((3, 2))},
    {'velocities': [[0.0, 0.0, np.inf]] * 3},
    {'joint_names': ('a', 'a', 'b')},
])
def test_data_checks_its_structure_on_construction(changes):
    fields = {'joint_names': NAMES, 'time_from_start': [0.0, 0.1, 0.2],
              'positions': np.zeros((3, 3)), 'velocities': np.zeros((3, 3)),
              'accelerations': np.zeros((3, 3))}
    JointTrajectoryData(**fields)
    fields.update(changes)
    with pytest.raises(InvalidInputError):
        JointTrajectoryData(**fields)


def test_data_of_valid_float_arrays_passes_the_same_checks():
    # Valid C-contiguous float arrays are checked in one compiled pass; it must reject
    # whatever the checks naming a problem reject, and those then name it.
    rng = np.random.default_rng(8)
    times = np.cumsum(rng.uniform(0.01, 0.1, 6)) - 0.01
    states = rng.normal(size=(3, 6, 3))
    JointTrajectoryData(NAMES, times, *states)  # valid
    cases = [({'time_from_start': np.where(np.arange(6) == 0, -0.0, times)}, None),
             ({'time_from_start': np.where(np.arange(6) == 0, -1e-9, times)},
              r'^time_from_start\[0\]: expected a time >= 0'),
             ({'time_from_start': np.where(np.arange(6) == 3, times[2], times)},
              r'^time_from_start\[3\]: expected a time > time_from_start\[2\]'),
             ({'time_from_start': np.where(np.arange(6) == 5, np.inf, times)},
              r'^time_from_start\[5\]: expected finite values'),
             ({'time_from_start': np.where(np.arange(6) == 0, np.nan, times)},
              r'^time_from_start\[0\]: expected finite values')]
    for index, field in enumerate(('positions', 'velocities', 'accelerations')):
        for bad in (np.nan, -np.inf):
            changed = states[index].copy()
            changed[4, index] = bad
            cases.append(({field: changed}, rf'^{field}\[4\]: expected finite values'))
    for changes, message in cases:
        fields = dict(zip(('time_from_start', 'positions', 'velocities', 'accelerations'),
                          (times, *states)), **changes)
        if message is None:
            data = JointTrajectoryData(NAMES, **fields)
            assert not data.positions.flags.writeable
            np.testing.assert_array_equal(data.time_from_start, fields['time_from_start'])
            continue
        with pytest.raises(InvalidInputError, match=message):
            JointTrajectoryData(NAMES, **fields)
        # The same from Fortran-order arrays (copied in C order) and lists (not compiled).
        fortran = {key: np.asfortranarray(value) if np.ndim(value) == 2 else list(value)
                   for key, value in fields.items()}
        with pytest.raises(InvalidInputError, match=message):
            JointTrajectoryData(NAMES, **fortran)


def test_data_is_read_only():
    traj = sample_joint_trajectory(LINE, GEOMETRY, 0.05)
    with pytest.raises(ValueError):
        traj.positions[0, 0] = 1.0
    assert traj.duration == LINE.duration


def hand_made(velocity=0.0, acceleration=0.0, position=0.5):
    """Four points at rest except joint_2 at t = 0.123 s."""
    times = np.array([0.0, 0.1, 0.123, 0.2])
    positions = np.full((4, 3), 0.5)
    velocities = np.zeros((4, 3))
    accelerations = np.zeros((4, 3))
    positions[2, 1], velocities[2, 1], accelerations[2, 1] = position, velocity, acceleration
    return JointTrajectoryData(NAMES, times, positions, velocities, accelerations)


@pytest.mark.parametrize('traj, message', [
    (hand_made(velocity=11.3),
     'joint_2 velocity: expected |q\u0307| \u2264 10 rad/s, got 11.3 at t=0.123 s'),
    (hand_made(velocity=-10.5),
     'joint_2 velocity: expected |q\u0307| \u2264 10 rad/s, got -10.5 at t=0.123 s'),
    (hand_made(acceleration=250.0),
     'joint_2 acceleration: expected |q\u0308| \u2264 200 rad/s^2, got 250 at t=0.123 s'),
    (hand_made(position=2.0),
     'joint_2 position: expected a value in [-0.85, 1.95] rad, got 2 at t=0.123 s'),
])
def test_joint_limits_name_the_first_offence(traj, message):
    with pytest.raises(LimitError) as caught:
        check_joint_limits(traj, GEOMETRY, JointLimits())
    assert str(caught.value) == message


def test_joint_limits_pass_and_fail_on_a_planned_motion():
    traj, _ = minimal_knots(ARC, GEOMETRY, NAMES)
    check_joint_limits(traj, GEOMETRY, JointLimits(), samples_per_segment=50)
    dense = sample_joint_trajectory(ARC, GEOMETRY, 0.001)
    peak = np.abs(dense.velocities).max()
    first = np.argmax((np.abs(dense.velocities) > 0.9 * peak).any(axis=1))
    when = dense.time_from_start[first]
    with pytest.raises(LimitError, match=rf'velocity: .*at t={when:.6g} s'):
        check_joint_limits(dense, GEOMETRY, JointLimits(max_velocity=0.9 * peak))


def test_joint_limits_between_knots_need_interpolation():
    # Two knots inside the range, moving fast: the quintic overshoots q_max between them.
    traj = JointTrajectoryData(NAMES, [0.0, 0.1], np.full((2, 3), 1.9),
                               np.array([[0.0, 5.0, 0.0], [0.0, -5.0, 0.0]]), np.zeros((2, 3)))
    check_joint_limits(traj, GEOMETRY, JointLimits())
    with pytest.raises(LimitError, match=r'^joint_2 position: expected a value in '):
        check_joint_limits(traj, GEOMETRY, JointLimits(), samples_per_segment=20)
    # With the executed table the segment near the bound is still walked.
    with pytest.raises(LimitError, match=r'^joint_2 position: expected a value in '):
        check_joint_limits(traj, GEOMETRY, JointLimits(), samples_per_segment=20,
                           table=executed_table(traj, GEOMETRY))


def test_joint_limits_from_the_table_name_an_extreme_between_the_samples():
    # Asymmetric ends: the speed peaks between the walk's samples (ends and middle).
    traj = JointTrajectoryData(NAMES, [0.0, 0.1], np.array([[0.1, 0.2, 0.3], [0.12, 0.6, 0.3]]),
                               np.array([[0.0, 1.0, 0.0], [0.0, -2.0, 0.0]]),
                               np.array([[0.0, 30.0, 0.0], [0.0, 0.0, 0.0]]))
    # Independently: the quintic's speed on a fine grid.
    t = np.linspace(0.0, 0.1, 1000001)
    speed = quintic_interpolate(traj, t)[1][:, 1]
    peak = int(np.argmax(np.abs(speed)))
    limits = JointLimits(max_velocity=0.9999 * abs(speed[peak]))
    table = executed_table(traj, GEOMETRY)
    # The samples alone miss it ...
    check_joint_limits(traj, GEOMETRY, limits, samples_per_segment=1)
    # ... the table's exact extreme does not, named at its own time and value.
    with pytest.raises(LimitError, match=r'^joint_2 velocity: expected ') as caught:
        check_joint_limits(traj, GEOMETRY, limits, samples_per_segment=1, table=table)
    value, when = str(caught.value).split(' got ')[1].split(' at t=')
    assert float(value) == pytest.approx(speed[peak], rel=1e-5)
    assert float(when.rstrip(' s')) == pytest.approx(t[peak], abs=2e-6)
    # A table of other knots is refused.
    with pytest.raises(InvalidInputError, match=r'^table: expected shape \(1, 5\)'):
        check_joint_limits(traj, GEOMETRY, limits, table=np.zeros((2, 5)))
