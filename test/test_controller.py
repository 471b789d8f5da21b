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
Tests of the Jazzy joint_trajectory_controller emulation against hand-checkable cases.

The reference profiles are written out here: the minimum-jerk quintic 10s^3 - 15s^4 + 6s^5
(0 -> 1 at rest), the cubic 3s^2 - 2s^3, straight lines, and quintics obtained by solving
the 6 x 6 boundary-value system with numpy, independently of the code's closed forms.
"""

from ellipath_ros.core.controller import distance_to_paths
from ellipath_ros.core.controller import executed_tcp
from ellipath_ros.core.controller import JazzyJtcEmulator
from ellipath_ros.core.controller import visit_times
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.joint_trajectory import DEFAULT_JOINT_NAMES
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import TrajectoryRejectedError
from ellipath_ros.core.kinematics import DeltaGeometry
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import inverse_kinematics
import numpy as np
import pytest

NAMES = DEFAULT_JOINT_NAMES
PERIOD = 0.001
# Joint j moves SCALE[j] times the scalar profile, so a mixed-up column shows.
SCALE = np.array([1.0, -0.5, 0.25])


def min_jerk(s):
    """Position, velocity, acceleration of 10s^3 - 15s^4 + 6s^5 (duration 1 s)."""
    return (10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4,
            60 * s - 180 * s**2 + 120 * s**3)


def quintic_through(h, start, end):
    """Coefficients c0..c5 of the quintic with (p, v, a) ``start`` at 0 and ``end`` at h."""
    rows = [[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 2, 0, 0, 0],
            [1, h, h**2, h**3, h**4, h**5], [0, 1, 2 * h, 3 * h**2, 4 * h**3, 5 * h**4],
            [0, 0, 2, 6 * h, 12 * h**2, 20 * h**3]]
    return np.linalg.solve(np.array(rows, dtype=float), np.array([*start, *end], dtype=float))


def polyval(coefficients, t):
    """Position of a polynomial given lowest order first."""
    return sum(c * t**k for k, c in enumerate(coefficients))


def scalar_trajectory(times, positions, velocities=None, accelerations=None, names=NAMES):
    """Return a trajectory whose joint j is SCALE[j] times the given scalar knots."""
    count = len(times)
    zeros = np.zeros(count)

    def joints(values):
        return np.outer(zeros if values is None else values, SCALE)

    return JointTrajectoryData(names, np.array(times, dtype=float), joints(positions),
                               joints(velocities), joints(accelerations))


def rows_between(samples, start, end):
    """Boolean mask of the samples with start < t < end (away from float ties)."""
    return (samples.times > start + 1e-9) & (samples.times < end - 1e-9)


def test_single_trajectory_is_the_quintic_through_its_points():
    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]),
                     stamp=0.0, receive_time=0.0)
    emulator.run_until(1.5)
    samples = emulator.samples()
    assert samples.times[-1] == pytest.approx(1.5)
    assert np.allclose(np.diff(samples.times), PERIOD)
    moving = samples.times <= 1.0
    expected = [np.outer(value, SCALE) for value in min_jerk(samples.times[moving])]
    np.testing.assert_allclose(samples.positions[moving], expected[0], atol=1e-12)
    np.testing.assert_allclose(samples.velocities[moving], expected[1], atol=1e-11)
    np.testing.assert_allclose(samples.accelerations[moving], expected[2], atol=1e-9)
    np.testing.assert_allclose(samples.positions[~moving], np.tile(SCALE, (500, 1)))
    assert not samples.velocities[~moving].any()
    assert samples.source[0] == -1 and (samples.source[1:] == 0).all()
    assert samples.pickup_times.tolist() == [0.0]


def test_stamp_zero_starts_at_the_cycle_that_takes_the_message_up():
    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]),
                     stamp=0.0, receive_time=0.0123)
    emulator.run_until(1.2)
    samples = emulator.samples()
    start = 0.013  # first cycle at or after the reception
    assert samples.pickup_times[0] == pytest.approx(start)
    assert not samples.positions[samples.times <= start + 1e-9].any()
    moving = rows_between(samples, start, start + 1.0)
    expected = np.outer(min_jerk(samples.times[moving] - start)[0], SCALE)
    np.testing.assert_allclose(samples.positions[moving], expected, atol=1e-12)


def replaced_at_a_quarter(velocity_state, receive_time):
    """Replace the min-jerk move by a point (2, at rest) due 0.5 s after pickup; samples."""
    emulator = JazzyJtcEmulator(NAMES, PERIOD, velocity_state=velocity_state)
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]),
                     stamp=0.0, receive_time=0.0)
    emulator.receive(scalar_trajectory([0.5], [2.0], [0.0], [0.0]), stamp=0.0,
                     receive_time=receive_time)
    emulator.run_until(1.0)
    return emulator.samples()


def assert_spline_from(samples, pickup, start_state):
    """Assert the rows in (pickup, pickup + 0.5) follow the quintic from start_state to 2."""
    coefficients = quintic_through(0.5, start_state, (2.0, 0.0, 0.0))
    spline = rows_between(samples, pickup, pickup + 0.5)
    expected = np.outer(polyval(coefficients, samples.times[spline] - pickup), SCALE)
    np.testing.assert_allclose(samples.positions[spline], expected, atol=1e-12)
    return coefficients


def test_replacement_mid_motion_splines_from_current_position_and_velocity_with_zero_accel():
    samples = replaced_at_a_quarter(velocity_state=True, receive_time=0.2495)
    pickup = 0.25
    assert samples.pickup_times[1] == pytest.approx(pickup)
    p, v, a = min_jerk(pickup)
    assert a == pytest.approx(5.625)  # the old trajectory was accelerating hard here
    at_pickup = int(np.argmin(np.abs(samples.times - pickup)))
    np.testing.assert_allclose(samples.accelerations[at_pickup], a * SCALE)
    coefficients = assert_spline_from(samples, pickup, (p, v, 0.0))
    # The new command starts from zero acceleration: a step from 5.6 rad/s^2 on joint 0.
    second_derivative = np.polynomial.polynomial.polyder(coefficients, 2)
    next_acceleration = samples.accelerations[at_pickup + 1, 0]
    assert next_acceleration == pytest.approx(polyval(second_derivative, PERIOD), rel=1e-9)
    assert abs(next_acceleration) < 1.0
    after = samples.times > pickup + 0.5 + 1e-9
    np.testing.assert_allclose(samples.positions[after], np.tile(2.0 * SCALE, (after.sum(), 1)))
    assert (samples.source[samples.times > pickup + 1e-9] == 1).all()


def test_without_velocity_state_the_replacement_starts_from_zero_velocity():
    samples = replaced_at_a_quarter(velocity_state=False, receive_time=0.25)
    p, v, _ = min_jerk(0.25)
    assert_spline_from(samples, 0.25, (p, 0.0, 0.0))
    first = np.flatnonzero(rows_between(samples, 0.25, 0.75))[0]
    assert samples.velocities[first - 1, 0] == pytest.approx(v, rel=1e-9)
    assert abs(samples.velocities[first, 0]) < 0.05 * v


def test_future_stamp_holds_until_the_stamp_when_at_rest_at_the_first_point():
    emulator = JazzyJtcEmulator(NAMES, PERIOD, start_time=100.0)
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]),
                     stamp=100.3, receive_time=100.0)
    emulator.run_until(101.5)
    samples = emulator.samples()
    waiting = samples.times <= 100.3 + 1e-9
    assert not samples.positions[waiting].any()
    moving = rows_between(samples, 100.3, 101.3)
    expected = np.outer(min_jerk(samples.times[moving] - 100.3)[0], SCALE)
    np.testing.assert_allclose(samples.positions[moving], expected, atol=1e-9)


def test_future_stamp_away_from_the_first_point_splines_to_reach_it_at_the_stamp():
    emulator = JazzyJtcEmulator(NAMES, PERIOD, start_time=100.0)
    emulator.receive(scalar_trajectory([0.0, 1.0], [1.0, 2.0], [0.0, 0.0], [0.0, 0.0]),
                     stamp=100.5, receive_time=100.1)
    emulator.run_until(102.0)
    samples = emulator.samples()
    coefficients = quintic_through(0.4, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    spline = rows_between(samples, 100.1, 100.5)
    expected = np.outer(polyval(coefficients, samples.times[spline] - 100.1), SCALE)
    np.testing.assert_allclose(samples.positions[spline], expected, atol=1e-9)
    at_stamp = int(np.argmin(np.abs(samples.times - 100.5)))
    np.testing.assert_allclose(samples.positions[at_stamp], SCALE, atol=1e-12)


def test_past_stamp_starts_mid_trajectory_with_a_jump():
    emulator = JazzyJtcEmulator(NAMES, PERIOD, start_time=10.0)
    # Its end (10.2 + 1) is still ahead at reception, so JTC accepts it, 0.3 s late.
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]),
                     stamp=10.2, receive_time=10.5)
    emulator.run_until(10.6)
    samples = emulator.samples()
    at_pickup = int(np.argmin(np.abs(samples.times - 10.5)))
    assert samples.positions[at_pickup, 0] == 0.0
    jump = samples.positions[at_pickup + 1, 0]
    assert jump == pytest.approx(min_jerk(0.301)[0], rel=1e-9)
    assert jump > 0.15  # one cycle asks for 15 % of the whole move


def test_stamp_whose_end_is_past_is_rejected_and_the_running_trajectory_continues():
    emulator = JazzyJtcEmulator(NAMES, PERIOD, start_time=10.0)
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]),
                     stamp=0.0, receive_time=10.0)
    with pytest.raises(TrajectoryRejectedError, match='header.stamp'):
        emulator.receive(scalar_trajectory([0.0, 1.0], [5.0, 6.0]), stamp=9.0,
                         receive_time=10.5)
    emulator.run_until(11.0)
    samples = emulator.samples()
    assert (samples.source[1:] == 0).all()
    assert samples.positions[-1, 0] == pytest.approx(1.0)


def test_positions_only_is_linear_and_positions_velocities_is_cubic():
    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0]), stamp=0.0, receive_time=0.0,
                     fields=('positions',))
    emulator.run_until(1.1)
    samples = emulator.samples()
    moving = rows_between(samples, 0.0, 1.0)
    np.testing.assert_allclose(samples.positions[moving],
                               np.outer(samples.times[moving], SCALE), atol=1e-12)
    np.testing.assert_allclose(samples.velocities[moving], np.tile(SCALE, (moving.sum(), 1)))
    assert not samples.accelerations.any()

    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 0.0]), stamp=0.0,
                     receive_time=0.0, fields=('positions', 'velocities'))
    emulator.run_until(1.1)
    samples = emulator.samples()
    s = samples.times[moving]
    np.testing.assert_allclose(samples.positions[moving], np.outer(3 * s**2 - 2 * s**3, SCALE),
                               atol=1e-12)
    np.testing.assert_allclose(samples.accelerations[moving], np.outer(6 - 12 * s, SCALE),
                               atol=1e-9)


def test_positions_and_accelerations_without_velocities_command_zero_as_jazzy_does():
    start = np.array([0.3, 0.3, 0.3])
    emulator = JazzyJtcEmulator(NAMES, PERIOD, initial_positions=start)
    trajectory = JointTrajectoryData(NAMES, [0.0, 1.0], [start, start + 0.2], np.zeros((2, 3)),
                                     [[0.1, 0.1, 0.1], [0.0, 0.0, 0.0]])
    emulator.receive(trajectory, stamp=0.0, receive_time=0.0,
                     fields=('positions', 'accelerations'))
    emulator.run_until(1.5)
    samples = emulator.samples()
    moving = rows_between(samples, 0.0, 1.0)
    assert not samples.positions[moving].any()
    np.testing.assert_allclose(samples.positions[samples.times > 1.0 + 1e-9], 0.5)


def test_later_reception_before_the_next_cycle_overwrites_the_pending_message():
    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    first = emulator.receive(scalar_trajectory([0.5], [1.0], [0.0], [0.0]), 0.0, 0.0101)
    second = emulator.receive(scalar_trajectory([0.5], [-1.0], [0.0], [0.0]), 0.0, 0.0104)
    emulator.run_until(1.0)
    samples = emulator.samples()
    assert np.isnan(samples.pickup_times[first])
    assert samples.pickup_times[second] == pytest.approx(0.011)
    assert first not in samples.source
    np.testing.assert_allclose(samples.positions[-1], -SCALE)


def test_joint_names_in_another_order_are_sorted_to_the_controller_order():
    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    reordered = (NAMES[2], NAMES[0], NAMES[1])
    emulator.receive(JointTrajectoryData(reordered, [0.1], [[3.0, 1.0, 2.0]], np.zeros((1, 3)),
                                         np.zeros((1, 3))), 0.0, 0.0)
    emulator.run_until(0.2)
    np.testing.assert_allclose(emulator.samples().positions[-1], [1.0, 2.0, 3.0])


@pytest.mark.parametrize('trajectory, fields, match', [
    (JointTrajectoryData(('a', 'b', 'c'), [0.1], np.zeros((1, 3)), np.zeros((1, 3)),
                         np.zeros((1, 3))), ('positions',), 'joint_names'),
    (scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 1e-3]), ('positions', 'velocities'),
     'velocities'),
    (scalar_trajectory([0.0, 0.1, 0.1 + 1e-10], [0.0, 1.0, 1.0]), ('positions',),
     'time_from_start'),
])
def test_messages_jtc_rejects_are_rejected(trajectory, fields, match):
    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    with pytest.raises(TrajectoryRejectedError, match=match):
        emulator.receive(trajectory, 0.0, 0.0, fields=fields)


def test_final_velocity_within_float_epsilon_is_accepted():
    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    emulator.receive(scalar_trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 1e-8]), 0.0, 0.0,
                     fields=('positions', 'velocities'))


def test_reception_before_cycles_already_run_is_refused():
    emulator = JazzyJtcEmulator(NAMES, PERIOD)
    emulator.run_until(0.5)
    with pytest.raises(InvalidInputError, match='receive_time'):
        emulator.receive(scalar_trajectory([0.1], [1.0]), 0.0, 0.499, fields=('positions',))
    emulator.receive(scalar_trajectory([0.1], [1.0]), 0.0, 0.5001, fields=('positions',))
    with pytest.raises(InvalidInputError, match='previous reception'):
        emulator.receive(scalar_trajectory([0.1], [1.0]), 0.0, 0.50005, fields=('positions',))


def test_executed_tcp_is_forward_kinematics_and_peaks_show_a_jump():
    geometry = DeltaGeometry()
    start = inverse_kinematics([0.0, 0.0, -0.8], geometry)
    end = inverse_kinematics([0.001, 0.0, -0.8], geometry)
    emulator = JazzyJtcEmulator(NAMES, PERIOD, initial_positions=start)
    emulator.run_until(0.0101)
    # Stamp in the past: the next cycle commands the end at once, a 1 mm step in one period.
    emulator.receive(JointTrajectoryData(NAMES, [0.0], [end], np.zeros((1, 3)),
                                         np.zeros((1, 3))), stamp=0.0, receive_time=0.0102)
    emulator.run_until(0.05)
    samples = emulator.samples()
    tcp = executed_tcp(samples, geometry)
    np.testing.assert_allclose(tcp.positions, forward_kinematics(samples.positions, geometry))
    assert tcp.peak_speed == pytest.approx(0.001 / PERIOD, rel=1e-6)
    assert tcp.peak_acceleration == pytest.approx(0.001 / PERIOD**2, rel=1e-6)

    still = executed_tcp(JazzyJtcEmulator(NAMES, PERIOD, initial_positions=start).samples(),
                         geometry)
    assert still.peak_speed == 0.0 and still.peak_jerk == 0.0


def test_distance_to_paths_takes_the_nearest_chord_of_any_path():
    line = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [1.0, 0.0, 0.0]])
    other = np.array([[0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    points = [[0.25, 0.2, 0.0], [-1.0, 0.0, 0.0], [0.7, 0.9, 0.0], [np.nan, 0.0, 0.0]]
    distances = distance_to_paths(points, [line, other], chunk=2)
    np.testing.assert_allclose(distances[:3], [0.2, 1.0, 0.1])
    assert np.isnan(distances[3])


def test_distance_to_paths_measures_each_path_on_its_own():
    # The nearest vertex overall is the short path's, 9 mm away, but the long chord passes
    # 1 mm from the point between its two far vertices.
    long_chord = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    short = np.array([[0.5, 0.01, 0.0], [0.5, 0.02, 0.0]])
    distance = distance_to_paths([[0.5, 0.001, 0.0]], [short, long_chord])
    assert distance[0] == pytest.approx(0.001)


def test_visit_times_require_the_order():
    times = np.arange(5.0)
    track = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 0, 0], [0, 0, 0]], dtype=float)
    in_order = visit_times(times, track, [[1, 0, 0], [2, 0, 0], [0, 0, 0]], 1e-3)
    np.testing.assert_allclose(in_order, [1.0, 2.0, 4.0])
    missing = visit_times(times, track, [[2, 0, 0], [3, 0, 0], [0, 0, 0]], 1e-3)
    assert missing[0] == 2.0 and np.isnan(missing[1:]).all()
