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
Joint trajectories for ros2_control's joint_trajectory_controller (JTC), without ROS.

A planned Cartesian motion (anything with the :class:`Motion` protocol) is turned into joint
knots with positions, velocities and accelerations. Given all three, JTC interpolates every
joint between consecutive knots with the quintic polynomial that matches them at both ends
(``Trajectory::interpolate_between_points`` in ``joint_trajectory_controller/src/
trajectory.cpp``); :func:`quintic_interpolate` reproduces it. The knot search
(:func:`~ellipath_ros.core.knots.minimal_knots`) picks few knots such that this interpolation,
mapped back through forward kinematics, stays within a tolerance of the planned TCP path, on
the motion's samples (:class:`MotionSamples`). :func:`validate_jtc` mirrors JTC's acceptance
rules and :func:`check_joint_limits` the actuator limits; :func:`executed_peaks` gives the peaks of
what JTC executes (its quintic through forward kinematics).

Arrays: times have shape (K,) [s]; positions, velocities and accelerations (K, 3)
[rad, rad/s, rad/s^2], column i for arm i (joint ``joint_names[i]``).
"""

from dataclasses import dataclass
import math
from typing import Protocol

from ellipath_ros.core.compiled import kernel
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import LimitError
from ellipath_ros.core.errors import require_range
from ellipath_ros.core.errors import UnreachableError
from ellipath_ros.core.kinematics import _ASSEMBLED
from ellipath_ros.core.kinematics import _kernel_geometry
from ellipath_ros.core.kinematics import _row
from ellipath_ros.core.kinematics import _tcp_state
from ellipath_ros.core.kinematics import joint_angles
from ellipath_ros.core.kinematics import joint_motion
from ellipath_ros.core.kinematics import joint_trig_peaks
from ellipath_ros.core.kinematics import tcp_derivatives
import numpy as np

DEFAULT_JOINT_NAMES = ('joint_1', 'joint_2', 'joint_3')

# The final point must be at rest: |v|, |a| below this. JTC itself rejects a final velocity
# above FLT_EPSILON (1.19e-7); we are stricter and also stop the acceleration.
REST_TOLERANCE = 1e-9

# Segments are accepted when the error on their check grid is below SAFETY * tolerance: the
# grid can miss the true peak between two samples by a little.
_SAFETY = 0.95
# Samples of a motion that has no sample set of its own: at most this far apart [s], plus its
# jerk steps.
_SAMPLE_PERIOD = 1e-4
# Samples closer than this share of the duration count as one time (both sides of a step).
_SAME_TIME = 1e-8
# A search for a time in sorted times, continued from where a lower one ended, walks this many
# steps before it bisects the rest (the knot search's wanted times come in order, mostly a
# step or two apart among the samples).
_WALK_STEPS = 8

# Executed (JTC-interpolated) peaks, in this order: TCP speed [m/s], acceleration [m/s^2] and
# jerk [m/s^3], joint speed [rad/s] and acceleration [rad/s^2].
EXECUTED_KEYS = ('peak_speed', 'peak_accel', 'peak_jerk', 'joint_peak_velocity',
                 'joint_peak_accel')
# Samples per knot segment for the executed TCP peaks (ends included: one more); each largest
# sample is refined by a parabola through its neighbours.
_EXECUTED_SAMPLES = 12
# Segments whose peak of a quantity is within this share of the trajectory's largest are
# searched for that quantity's maximum: the base samples and their parabola can miss a
# sharp peak by a few 0.1 % (0.25 % seen), so a peak missed by less than this share is
# still in a searched segment. Reported peaks must not be more than 0.1 % under a 1 MHz
# check.
_EXECUTED_REFINE_SHARE = 0.02
# Local maxima of a quantity's samples searched per segment (the largest ones), and the
# search's resolution (share of a sample interval) and its largest number of steps.
_EXECUTED_CANDIDATES = 3
_EXECUTED_SEARCH_TOLERANCE = 1e-2
_EXECUTED_SEARCH_STEPS = 40
# Golden-section step of the search: (3 - sqrt(5)) / 2.
_GOLDEN_SECTION = 0.3819660112501051
# Bisections for a root of the joint acceleration (halves the stretch each time).
_BISECTIONS = 40


class Motion(Protocol):
    """A planned TCP motion, as the planner delivers it."""

    duration: float  # s, > 0

    def state_at(self, t):
        """
        Return TCP position, velocity, acceleration and jerk at times ``t``.

        ``t`` has shape (N,) with values in [0, duration]; each returned array has shape
        (N, 3), base frame, SI units.
        """


class TrajectoryRejectedError(InvalidInputError):
    """A joint trajectory that joint_trajectory_controller would (or should) reject."""


@dataclass(frozen=True, eq=False)
class JointTrajectoryData:
    """
    A joint trajectory ready to become a ``trajectory_msgs/JointTrajectory``.

    Attributes
    ----------
    joint_names : tuple of str
        Three unique joint names, arm 0, 1, 2.
    time_from_start : numpy.ndarray, shape (K,)
        Times of the points [s], >= 0 and strictly increasing, K >= 1.
    positions : numpy.ndarray, shape (K, 3)
        Joint angles [rad].
    velocities : numpy.ndarray, shape (K, 3)
        Joint velocities [rad/s].
    accelerations : numpy.ndarray, shape (K, 3)
        Joint accelerations [rad/s^2].

    The arrays are read-only float copies; every entry is finite. Whether the last point is
    at rest, and the names expected by the controller, are checked by :func:`validate_jtc`.

    """

    joint_names: tuple
    time_from_start: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    def __post_init__(self):
        """Convert to read-only float arrays and check their shapes and values."""
        fields = _check_structure(self, InvalidInputError)
        for field, value in zip(('joint_names', 'time_from_start', 'positions', 'velocities',
                                 'accelerations'), fields):
            object.__setattr__(self, field, value)

    @property
    def duration(self):
        """Time of the last point [s]."""
        return float(self.time_from_start[-1])

    @classmethod
    def _chained(cls, joint_names, time_from_start, positions, velocities, accelerations):
        """
        Return the points of a chain of checked trajectories, not checked again.

        For the planner's chains of legs and rests only, whose end is checked whole by
        :func:`validate_jtc` (after :func:`on_whole_nanoseconds`) before it is used: the
        arrays, new float arrays made from the points of checked trajectories, are kept (made
        read-only), not copied.
        """
        trajectory = object.__new__(cls)
        object.__setattr__(trajectory, 'joint_names', joint_names)
        for field, array in zip(_POINT_FIELDS, (time_from_start, positions, velocities,
                                                accelerations)):
            array.setflags(write=False)
            object.__setattr__(trajectory, field, array)
        return trajectory


def _check_structure(traj, error):
    """
    Check names, times and the three (K, 3) arrays of ``traj``; return them converted.

    Duck-typed: ``traj`` needs the attributes of :class:`JointTrajectoryData`, holding any
    array-likes. Raises ``error`` naming the first problem.
    """
    names = getattr(traj, 'joint_names', None)
    if isinstance(names, str) or not hasattr(names, '__len__'):
        raise error(f'joint_names: expected a sequence of 3 names, got {names!r}')
    names = tuple(names)
    if len(names) == 0:
        raise error('joint_names: expected 3 names, got none (JTC: "Empty joint names")')
    if not all(isinstance(item, str) and item for item in names):
        raise error(f'joint_names: expected non-empty strings, got {names!r}')
    if len(set(names)) != len(names):
        raise error(f'joint_names: expected unique names, got {names!r}')
    if len(names) != 3:
        # JTC rejects partial goals unless allow_partial_joints_goal is set (default false).
        raise error(f'joint_names: expected 3 names (one per arm), got {len(names)}')
    values = [getattr(traj, field, None) for field in _POINT_FIELDS]
    if _float_point_arrays(values):
        # Float arrays, as the planner makes them: their copies (C order and writeable, the
        # one array type the kernel is compiled for) checked in one compiled pass.
        arrays = [value.copy() for value in values]
        if _valid_points(*arrays):
            for array in arrays:
                array.setflags(write=False)
            return (names, *arrays)
    times = _float_array(traj, 'time_from_start', error)
    if times.ndim != 1 or times.size == 0:
        raise error(f'time_from_start: expected shape (K,) with K >= 1 points, got shape '
                    f'{times.shape}')
    count = times.size
    _require_finite_rows('time_from_start', times[:, np.newaxis], error)
    if times[0] < 0.0:
        raise error(f'time_from_start[0]: expected a time >= 0 s, got {times[0]!r}')
    steps = np.diff(times)
    if (steps <= 0.0).any():
        index = int(np.argmax(steps <= 0.0)) + 1
        raise error(f'time_from_start[{index}]: expected a time > time_from_start[{index - 1}]'
                    f' = {times[index - 1]!r} s (strictly increasing), got {times[index]!r}')
    arrays = []
    for field in ('positions', 'velocities', 'accelerations'):
        array = _float_array(traj, field, error)
        if array.shape != (count, len(names)):
            raise error(f'{field}: expected shape ({count}, {len(names)}) (one row of '
                        f'{len(names)} per point), got shape {array.shape}')
        _require_finite_rows(field, array, error)
        arrays.append(array)
    return (names, times, *arrays)


# The array fields of JointTrajectoryData: times (K,), then (K, 3) per joint state.
_POINT_FIELDS = ('time_from_start', 'positions', 'velocities', 'accelerations')


def _float_point_arrays(values):
    """
    Return whether ``values`` (``_POINT_FIELDS`` order) are float arrays of the right shapes.

    Those are checked in one compiled pass (:func:`_valid_points`); anything else, and any
    that fails it, by the checks that name the problem. Plain NumPy arrays (a subclass's
    copy would keep its class) of NumPy's own float dtype, tested by identity (a comparison
    with ``np.float64`` costs three times as much; another float dtype object takes the
    other checks, to the same result).
    """
    times = values[0]
    if not (type(times) is np.ndarray and times.dtype is _FLOAT and times.ndim == 1
            and times.size > 0):
        return False
    shape = (times.size, 3)
    for value in values[1:]:
        if not (type(value) is np.ndarray and value.dtype is _FLOAT
                and value.shape == shape):
            return False
    return True


_FLOAT = np.dtype(np.float64)


@kernel
def _valid_points(times, positions, velocities, accelerations):
    """Return whether all values are finite and the times >= 0 and strictly increasing."""
    if not times[0] >= 0.0:
        return False
    for point in range(times.size):
        if not math.isfinite(times[point]) or (point > 0 and not times[point] > times[
                point - 1]):
            return False
        for j in range(3):
            if not (math.isfinite(positions[point, j]) and math.isfinite(velocities[point, j])
                    and math.isfinite(accelerations[point, j])):
                return False
    return True


def _float_array(traj, field, error):
    """Return a read-only float copy of ``traj.field``, or raise ``error``."""
    value = getattr(traj, field, None)
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise error(f'{field}: expected an array of finite numbers, got {value!r}') from None
    array.setflags(write=False)
    return array


def _require_finite_rows(field, array, error):
    """Raise ``error`` naming the first row of ``array`` with a non-finite entry."""
    # The whole-array test first: a per-row reduction over 3 columns costs ten times as much.
    if not np.isfinite(array).all():
        index = int(np.argmin(np.isfinite(array).all(axis=1)))
        raise error(f'{field}[{index}]: expected finite values, got {array[index].tolist()}')


def validate_jtc(traj, expect_names=None):
    """
    Raise unless joint_trajectory_controller (Jazzy) accepts ``traj`` and stops at its end.

    Mirrors ``JointTrajectoryController::validate_trajectory_msg`` in
    ros-controls/ros2_controllers, ``joint_trajectory_controller/src/
    joint_trajectory_controller.cpp`` (the "// CHECK:" version of the Jazzy line), which
    rejects a message when:

    * ``joint_names`` is empty ("Empty joint names on incoming trajectory"), has another size
      than the controller's joints while ``allow_partial_joints_goal`` is false (the default),
      or names a joint the controller does not have;
    * ``points`` is empty ("Empty trajectory received");
    * the last point has a velocity above ``FLT_EPSILON`` while
      ``allow_nonzero_velocity_at_trajectory_end`` is false (the default since Jazzy,
      ros2_controllers #834);
    * ``header.stamp`` is non-zero and stamp + last ``time_from_start`` is in the past (zero
      means "start now");
    * ``time_from_start`` is not strictly increasing, compared as ``rclcpp::Duration`` (whole
      nanoseconds) from point 1 on; the first point's time is not checked, and 0 is allowed;
    * a point's positions differ in size from ``joint_names``, or its velocities or
      accelerations are neither empty nor of that size (empty ones are accepted);
    * a point has effort entries and the controller has no effort command interface.

    JTC does not check for NaN. This function is stricter where a stricter rule is what we
    need: exactly 3 unique names (equal to ``expect_names`` in order, if given; JTC would
    also accept a permutation), velocities and accelerations present (the quintic
    interpolation needs both), every value finite, times >= 0 and distinct in nanoseconds,
    final velocity and acceleration within REST_TOLERANCE of zero. Not represented here and
    left to the ROS layer: publish ``header.stamp`` zero, no effort entries. A first point at
    ``time_from_start`` 0 is commanded immediately, with no interpolation from the current
    state, so it must be where the robot is.

    Parameters
    ----------
    traj : JointTrajectoryData or any object with the same attributes
        The trajectory; the attributes may hold array-likes (e.g. lists from a message).
    expect_names : sequence of str, optional
        The controller's joints, in order.

    Raises
    ------
    TrajectoryRejectedError
        Naming the first broken rule (a subclass of InvalidInputError).

    """
    names, times, _, velocities, accelerations = _check_structure(
        traj, TrajectoryRejectedError)
    if expect_names is not None and names != tuple(expect_names):
        raise TrajectoryRejectedError(
            f'joint_names: expected {tuple(expect_names)!r}, got {names!r}')
    index = _first_same_nanosecond(times)
    if index > 0:
        raise TrajectoryRejectedError(
            f'time_from_start[{index}]: expected a time at least 1 ns after '
            f'{times[index - 1]!r} s (JTC compares whole nanoseconds), got {times[index]!r}')
    for field, values, unit in (('velocities', velocities, 'rad/s'),
                                ('accelerations', accelerations, 'rad/s^2')):
        for joint, value in enumerate(values[-1].tolist()):
            if abs(value) >= REST_TOLERANCE:
                raise TrajectoryRejectedError(
                    f'{field}[-1] of {names[joint]}: expected 0 {unit} at the last point '
                    f'(|value| < {REST_TOLERANCE:g}), got {values[-1, joint]!r}')


@kernel
def _first_same_nanosecond(times):
    """
    Return the first point not after the one before in whole nanoseconds, or 0 if none is.

    The times rounded half to even, as ``numpy.round`` rounds them.
    """
    for point in range(1, times.size):
        if np.rint(times[point] * 1e9) - np.rint(times[point - 1] * 1e9) <= 0.0:
            return point
    return 0


def quintic_interpolate(traj, t):
    """
    Sample the trajectory the way JTC does when positions, velocities, accelerations are set.

    Between knots k and k+1 every joint follows the quintic polynomial matching position,
    velocity and acceleration at both ends (``Trajectory::interpolate_between_points``);
    sample k applies for ``t_k <= t < t_(k+1)``. At and after the last knot JTC holds the last
    point. Before the first knot JTC interpolates from the robot's state at reception, which
    is not known here: this returns the first point there.

    Parameters
    ----------
    traj : JointTrajectoryData
        The knots.
    t : array_like, shape (N,) or scalar
        Times from start [s].

    Returns
    -------
    tuple of numpy.ndarray
        Positions [rad], velocities [rad/s], accelerations [rad/s^2], each (N, 3) (or (3,)
        for a scalar ``t``).

    """
    times = np.asarray(t, dtype=float)
    scalar = times.ndim == 0
    result = _interpolated(traj, np.atleast_1d(times), 2)
    return tuple(array[0] for array in result) if scalar else result


def quintic_positions(traj, t):
    """
    Positions only of :func:`quintic_interpolate`, cheaper for many samples.

    No derivative is evaluated.

    Parameters
    ----------
    traj : JointTrajectoryData
        The knots.
    t : array_like, shape (N,)
        Times from start [s].

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        Positions [rad].

    """
    return _interpolated(traj, np.atleast_1d(np.asarray(t, dtype=float)), 0)[0]


def _interpolated(traj, times, order):
    """
    Return JTC's position (and derivatives up to ``order``, at most 2) at ``times`` (N,).

    The coefficients are computed once per knot segment, not once per sample.
    """
    knots = traj.time_from_start
    sources = (traj.positions, traj.velocities, traj.accelerations)[:order + 1]
    if knots.size == 1:
        hold = np.zeros(times.shape, dtype=int)
        return tuple(source[hold] for source in sources)
    starts = np.arange(knots.size - 1)
    coefficients = np.ascontiguousarray(_quintic_coefficients(traj, starts, starts + 1))
    values = np.empty((order + 1, times.size, 3))
    _interpolate_rows(coefficients, knots, np.ascontiguousarray(times),
                      np.stack(sources)[:, -1], values)
    return tuple(values)


@kernel
def _interpolate_rows(coefficients, knots, times, last, values):
    """
    Fill ``values`` (D + 1, N, 3) with JTC's position and D derivatives at ``times`` (N,).

    In the segment whose start is the last knot <= t (the first before the first knot),
    by :func:`_polynomial`; from the last knot on, ``last`` (D + 1, 3).
    """
    order = values.shape[0] - 1
    final = knots.size - 2
    for row in range(times.size):
        time = times[row]
        if time >= knots[-1]:
            values[:, row, :] = last
            continue
        segment = min(max(np.searchsorted(knots, time, side='right') - 1, 0), final)
        x = time - knots[segment]
        if x < 0.0:
            x = 0.0
        c = coefficients[segment]
        for derivative in range(order + 1):
            for j in range(3):
                values[derivative, row, j] = _polynomial(c, j, x, derivative)


def _quintic_coefficients(knots, start, end):
    """
    Polynomial coefficients in powers of ``t - t_start``, shape (S, 6, 3).

    ``knots`` has the attributes of JointTrajectoryData, ``start`` and ``end`` are index
    arrays (S,); see :func:`interpolation_coefficients`.
    """
    return interpolation_coefficients(
        knots.time_from_start[end] - knots.time_from_start[start],
        knots.positions[start], knots.positions[end], knots.velocities[start],
        knots.velocities[end], knots.accelerations[start], knots.accelerations[end])


def interpolation_coefficients(duration, q0, q1, v0=None, v1=None, a0=None, a1=None):
    """
    Coefficients of JTC's ``Trajectory::interpolate_between_points``, shape (S, 6, 3).

    Row ``[s, k, j]`` multiplies ``(t - t_start)^k`` for joint j of segment s; unused orders
    are 0, so one evaluation (:func:`evaluate_polynomials`) serves every degree. JTC picks
    the degree from which fields both ends carry (``None`` = empty in the message):

    * velocities and accelerations: quintic matching p, v, a at both ends;
    * velocities only: cubic matching p, v;
    * neither: linear in p (constant velocity, zero acceleration);
    * accelerations without velocities: JTC (Jazzy) has no branch for this case and leaves
      its freshly zeroed output, so it commands position 0 rad, velocity 0, acceleration 0;
      reproduced here because that is what the controller does.

    Parameters
    ----------
    duration : array_like, shape (S,)
        Segment lengths [s], > 0.
    q0, q1 : array_like, shape (S, 3)
        Positions at the start and end [rad].
    v0, v1 : array_like, shape (S, 3), or None
        Velocities [rad/s].
    a0, a1 : array_like, shape (S, 3), or None
        Accelerations [rad/s^2].

    Returns
    -------
    numpy.ndarray, shape (S, 6, 3)

    """
    q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    h = np.asarray(duration, dtype=float)[:, np.newaxis]
    coefficients = np.zeros((q0.shape[0], 6, q0.shape[1]))
    has_velocity = v0 is not None and v1 is not None
    has_acceleration = a0 is not None and a1 is not None
    if has_acceleration and not has_velocity:
        return coefficients
    if has_acceleration:
        _quintic_rows(h[:, 0], q0, q1, *(np.asarray(value, dtype=float)
                                         for value in (v0, v1, a0, a1)), coefficients)
        return coefficients
    dq = q1 - q0
    coefficients[:, 0] = q0
    if not has_velocity:
        coefficients[:, 1] = dq / h
        return coefficients
    v0, v1 = np.asarray(v0, dtype=float), np.asarray(v1, dtype=float)
    h2 = h * h
    coefficients[:, 1] = v0
    coefficients[:, 2] = (3.0 * dq - (2.0 * v0 + v1) * h) / h2
    coefficients[:, 3] = (-2.0 * dq + (v0 + v1) * h) / (h2 * h)
    return coefficients


@kernel
def _quintic_rows(h, q0, q1, v0, v1, a0, a1, coefficients):
    """Fill the quintic ``coefficients`` (S, 6, 3) of :func:`interpolation_coefficients`."""
    for row in range(h.size):
        _fill_quintic(h[row], q0, q1, v0, v1, a0, a1, row, row, coefficients[row])


@kernel
def _fill_quintic(length, q0, q1, v0, v1, a0, a1, first, second, c):
    """
    Fill ``c`` (6, 3) with JTC's quintic from row ``first`` of q0, v0, a0 to ``second`` of q1...

    The one form of the coefficients: every quintic of this module is built here.
    """
    h2 = length * length
    for j in range(3):
        dq = q1[second, j] - q0[first, j]
        start_v, end_v = v0[first, j], v1[second, j]
        start_a, end_a = a0[first, j], a1[second, j]
        c[0, j] = q0[first, j]
        c[1, j] = start_v
        c[2, j] = 0.5 * start_a
        c[3, j] = (20.0 * dq - (8.0 * end_v + 12.0 * start_v) * length
                   - (3.0 * start_a - end_a) * h2) / (2.0 * h2 * length)
        c[4, j] = (-30.0 * dq + (14.0 * end_v + 16.0 * start_v) * length
                   + (3.0 * start_a - 2.0 * end_a) * h2) / (2.0 * h2 * h2)
        c[5, j] = (12.0 * dq - 6.0 * (end_v + start_v) * length
                   - (start_a - end_a) * h2) / (2.0 * h2 * h2 * length)


def evaluate_polynomials(coefficients, offset, derivatives=True):
    """
    Position, velocity, acceleration of polynomials (S, 6, 3) at offsets (S, M) [s].

    Returns three arrays of shape (S, M, 3), or only the positions if not ``derivatives``.
    """
    if not derivatives:
        return _evaluate(coefficients, offset, 0)[0]
    return _evaluate(coefficients, offset, 2)


def _evaluate(coefficients, offset, order):
    """Return the polynomials (S, 6, J) and their derivatives up to ``order`` at (S, M)."""
    coefficients = np.ascontiguousarray(coefficients, dtype=float)
    offset = np.ascontiguousarray(offset, dtype=float)
    values = np.empty((order + 1,) + offset.shape + (coefficients.shape[2],))
    _polynomial_rows(coefficients, offset, values)
    return tuple(values)


@kernel
def _polynomial_rows(coefficients, offsets, values):
    """Fill ``values`` (D + 1, S, M, J) with polynomials (S, 6, J) and D derivatives."""
    for segment in range(offsets.shape[0]):
        c = coefficients[segment]
        for sample in range(offsets.shape[1]):
            x = offsets[segment, sample]
            for derivative in range(values.shape[0]):
                for j in range(c.shape[1]):
                    values[derivative, segment, sample, j] = _polynomial(c, j, x, derivative)


@kernel(inline=True)
def _polynomial(c, j, x, derivative):
    """
    Return the ``derivative``-th derivative (0 to 3) of column j of ``c`` (6, J) at ``x``.

    The one evaluation of JTC's polynomials (``sum c[k] x**k``, Horner's scheme) in this
    module.
    """
    if derivative == 0:
        return ((((c[5, j] * x + c[4, j]) * x + c[3, j]) * x + c[2, j]) * x + c[1, j]) * x + (
            c[0, j])
    if derivative == 1:
        return (((5.0 * c[5, j] * x + 4.0 * c[4, j]) * x + 3.0 * c[3, j]) * x
                + 2.0 * c[2, j]) * x + c[1, j]
    if derivative == 2:
        return ((20.0 * c[5, j] * x + 12.0 * c[4, j]) * x + 6.0 * c[3, j]) * x + 2.0 * c[2, j]
    return (60.0 * c[5, j] * x + 24.0 * c[4, j]) * x + 6.0 * c[3, j]


def _motion_duration(motion):
    """Return the motion's duration, checked."""
    return require_range('motion.duration', getattr(motion, 'duration', None), 0.0,
                         low_open=True, unit='s')


def _checked_state_at(motion, times):
    """Call ``motion.state_at`` and check what comes back: four finite (N, 3) arrays."""
    result = motion.state_at(times)
    try:
        arrays = [np.asarray(item, dtype=float) for item in result]
    except (TypeError, ValueError):
        raise InvalidInputError('motion.state_at: expected 4 arrays of shape (N, 3), got '
                                f'{type(result).__name__}') from None
    shapes = [array.shape for array in arrays]
    if shapes != [(times.size, 3)] * 4:
        raise InvalidInputError(f'motion.state_at: expected 4 arrays of shape '
                                f'({times.size}, 3), got shapes {shapes}')
    for name, array in zip(('position', 'velocity', 'acceleration'), arrays):
        if not np.isfinite(array).all():
            index = int(np.argmin(np.isfinite(array).all(axis=1)))
            raise InvalidInputError(f'motion {name} at t={times[index]:.6g} s: expected '
                                    f'finite values, got {array[index].tolist()}')
    return arrays


def _joint_states(motion, geometry, times):
    """Joint positions, velocities and accelerations of the motion at ``times`` (N,)."""
    points, velocities, accelerations, _ = _checked_state_at(motion, times)
    return _joint_motion_at(times, points, velocities, accelerations, geometry)


def _joint_motion_at(times, points, velocities, accelerations, geometry, convert=joint_motion):
    """Return ``convert`` (:func:`joint_motion`) of TCP states at ``times``, errors naming time."""
    try:
        return convert(points, velocities, accelerations, geometry, name='TCP position')
    except UnreachableError as error:
        index = error.index
        wrapped = UnreachableError(f'motion at t={times[index]:.6g} s: {error}')
        wrapped.index = index
        raise wrapped from error


def _names(joint_names):
    """Return the joint names as a tuple of 3 unique non-empty strings."""
    names = tuple(joint_names)
    if (len(names) != 3 or len(set(names)) != 3
            or not all(isinstance(item, str) and item for item in names)):
        raise InvalidInputError(f'joint_names: expected 3 unique names, got {names!r}')
    return names


def on_whole_nanoseconds(trajectory):
    """
    Return ``trajectory`` with each point moved along its own motion to a whole nanosecond.

    A JointTrajectory message carries whole nanoseconds. Rounding a point's time by up to
    0.5 ns with its state kept makes the quintic of a short segment miss the motion: across
    0.1 ms segments JTC's jerk rose up to 30 times the planned one, across 10 us segments
    without bound. Each point is instead moved to its rounded time by the Taylor step of
    its state, with the joint jerk of the segment it moves into (its mean, from the two
    accelerations): what is left, the jerk's change within 0.5 ns, is below 1e-9 of the
    state. The last point, at rest, only moves later (up to 1 ns), into its rest. The
    message then rounds nothing.
    """
    moved, times, positions, velocities, accelerations = _on_whole_nanoseconds(
        trajectory.time_from_start, trajectory.positions, trajectory.velocities,
        trajectory.accelerations)
    if not moved:
        return trajectory
    return JointTrajectoryData(trajectory.joint_names, times, positions, velocities,
                               accelerations)


@kernel
def _on_whole_nanoseconds(times, positions, velocities, accelerations):
    """
    Return (moved, times, q, q_dot, q_ddot) of :func:`on_whole_nanoseconds`; moved: any point.

    The arithmetic of its NumPy form, element by element: the times rounded (half to even)
    to whole nanoseconds, the last one up; each point's shift along the Taylor step of its
    state with the segment jerk ``diff(q_ddot) / max(diff(t), 1e-12)`` of the segment after
    it (a forward shift) or before it (a backward one), none past either end.
    """
    count = times.size
    whole = np.empty(count)
    moved = False
    for point in range(count):
        nanoseconds = np.rint(times[point] * 1e9)
        if point == count - 1:
            # The last point (at rest) goes later, never earlier: the robot rests there, so
            # its state stays exactly at rest, as the controller's rules want the end.
            nanoseconds = float(math.ceil(times[point] * 1e9 - 1e-6))
        whole[point] = nanoseconds * 1e-9
        moved = moved or whole[point] - times[point] != 0.0
    moved_positions = np.empty((count, 3))
    moved_velocities = np.empty((count, 3))
    moved_accelerations = np.empty((count, 3))
    if not moved:
        return False, whole, moved_positions, moved_velocities, moved_accelerations
    for point in range(count):
        shift = whole[point] - times[point]
        # Forward shifts move into the segment after the point, backward ones into the one
        # before.
        segment = point if shift > 0.0 else point - 1
        for j in range(3):
            jerk = 0.0
            if 0 <= segment < count - 1:
                jerk = (accelerations[segment + 1, j] - accelerations[segment, j]) / max(
                    times[segment + 1] - times[segment], 1e-12)
            acceleration, velocity = accelerations[point, j], velocities[point, j]
            moved_positions[point, j] = positions[point, j] + shift * (velocity + shift * (
                acceleration / 2.0 + shift * jerk / 6.0))
            moved_velocities[point, j] = velocity + shift * (acceleration + shift * jerk / 2.0)
            moved_accelerations[point, j] = acceleration + shift * jerk
    return True, whole, moved_positions, moved_velocities, moved_accelerations


def sample_joint_trajectory(motion, geometry, period, joint_names=DEFAULT_JOINT_NAMES):
    """
    Sample the motion at a fixed period and convert every sample to joint space.

    Parameters
    ----------
    motion : Motion
        The planned TCP motion.
    geometry : DeltaGeometry
        Robot dimensions and joint position limits.
    period : float
        Sampling period [s], > 0. Samples are at ``0, period, 2 period, ...`` and exactly at
        ``duration``; a regular sample closer than ``1e-6 period`` to ``duration`` is dropped,
        so the last interval lies in ``(1e-6 period, period * (1 + 1e-6)]``.
    joint_names : sequence of str
        Names of the three joints, arm 0, 1, 2.

    Returns
    -------
    JointTrajectoryData
        One point per sample.

    Raises
    ------
    UnreachableError
        A sample is outside the workspace or at a singularity (names its time).

    """
    names = _names(joint_names)
    duration = _motion_duration(motion)
    step = require_range('period', period, 0.0, low_open=True, unit='s')
    count = int(math.floor(duration / step))
    times = np.arange(count + 1) * step
    times = times[times < duration - 1e-6 * step]
    times = np.append(times, duration)
    q, qdot, qddot = _joint_states(motion, geometry, times)
    return JointTrajectoryData(names, times, q, qdot, qddot)


class MotionSamples:
    """
    A motion sampled once, in TCP and joint space.

    The knot search, the points added at jerk steps, the planned joint peaks
    and the knots' TCP positions all read these samples instead of evaluating
    the motion again: a knot is placed on the sample nearest to where a rule
    wants it (:meth:`states`), and the motion is evaluated only where no
    sample is near enough. A timed motion brings its own samples (those of its
    final limit check, ``sampled_states``: even steps at most 0.2 ms apart, at
    least two, across each constant-jerk piece of its law and both sides of every
    piece bound; the curvature profile's 4 even steps across each of its pieces);
    any other motion is sampled every ``_SAMPLE_PERIOD`` and at its jerk steps. A uniform slow-down
    (:meth:`scaled`) only rescales them: the joint motion of a motion slowed
    down by f is the same joint path with velocities / f and accelerations /
    f**2.

    Attributes
    ----------
    motion : Motion
        The sampled motion.
    times : numpy.ndarray
        Sample times [s], (N,), sorted, from 0 to the duration.
    position, velocity, acceleration, jerk : numpy.ndarray
        TCP states at ``times`` [m, m/s, m/s^2, m/s^3], (N, 3).
    cos_q, sin_q, qdot, qddot : numpy.ndarray
        Joint states at ``times`` [1, 1, rad/s, rad/s^2], (N, 3): the cosines and sines of
        the joint positions, whose angles :attr:`q` gives.

    """

    def __init__(self, motion, geometry, times, tcp, joints=None):
        """Keep the samples; ``joints`` (cos q, sin q, q_dot, q_ddot) computed when not given."""
        self.motion, self.geometry = motion, geometry
        self.times = times
        self.position, self.velocity, self.acceleration, self.jerk = tcp
        position, velocity, acceleration = tcp[:3]
        self._joint_peaks = None
        if joints is None:
            *joints, peak_velocity, peak_accel = _joint_motion_at(
                times, position, velocity, acceleration, geometry, joint_trig_peaks)
            self._joint_peaks = peak_velocity, peak_accel
        # The joint angles are computed only where they are read (their atan2 took more than
        # half of the joint states' time; the knot search reads the rows of its knots only).
        self.cos_q, self.sin_q, self.qdot, self.qddot = joints
        self._q = None
        self._planned = None
        self._peak_arrays = None

    @classmethod
    def of(cls, motion, geometry):
        """Sample ``motion`` (its own sample set if it has one) and convert to joint space."""
        sampled = getattr(motion, 'sampled_states', None)
        if sampled is not None:
            times, *tcp = sampled()
        else:
            duration = _motion_duration(motion)
            times = np.linspace(0.0, duration, max(2, math.ceil(duration / _SAMPLE_PERIOD)) + 1)
            steps = getattr(motion, 'jerk_steps', None)
            if steps is not None:
                times = np.union1d(times, steps()[0])
            tcp = _checked_state_at(motion, times)
        return cls(motion, geometry, times, tcp)

    @property
    def duration(self):
        """Time of the last sample [s]."""
        return float(self.times[-1])

    def scaled(self, factor, motion):
        """Return the samples of ``motion``, this motion slowed down uniformly by ``factor``."""
        if factor == 1.0:
            return self
        return MotionSamples(
            motion, self.geometry, self.times * factor,
            (self.position, self.velocity / factor, self.acceleration / factor ** 2,
             self.jerk / factor ** 3),
            (self.cos_q, self.sin_q, self.qdot / factor, self.qddot / factor ** 2))

    @property
    def q(self):
        """Joint positions at ``times`` [rad], (N, 3): the atan2 of every sample, kept."""
        if self._q is None:
            self._q = joint_angles(self.cos_q, self.sin_q)
        return self._q

    def joint_peaks(self):
        """Return the largest |q_dot| [rad/s] and |q_ddot| [rad/s^2] of the samples."""
        if self._joint_peaks is None:
            # Joint states given: the peaks were not found as they were made.
            self._joint_peaks = (float(np.abs(self.qdot).max()),
                                 float(np.abs(self.qddot).max()))
        return self._joint_peaks

    def segment_peaks(self, times):
        """
        Return the planned peaks on each interval of ``times`` (K,), (K - 1, 5).

        In the order of ``EXECUTED_KEYS``: largest TCP speed, acceleration and
        jerk norm, joint speed and acceleration of the samples in the interval,
        both ends included.
        """
        peaks = np.empty((times.size - 1, len(EXECUTED_KEYS)))
        _interval_peaks(*self._peak_source(), np.ascontiguousarray(times, dtype=float), peaks)
        return peaks

    def segments_beyond(self, times, table, bounds, share):
        """
        Return the intervals of ``times`` (K,) where ``table`` breaks a bound beyond the motion.

        Their indices (sorted): those where, in one same quantity, ``table`` (K - 1, 5) exceeds
        ``bounds`` (5,) and ``share`` times the planned peak of :meth:`segment_peaks`; the
        planned peaks are read only where a bound is exceeded.
        """
        return _segments_beyond(*self._peak_source(), np.ascontiguousarray(times, dtype=float),
                                np.ascontiguousarray(table, dtype=float),
                                np.ascontiguousarray(bounds, dtype=float), share)

    def _peak_source(self):
        """Return the samples' times and the (N, 3) rates the planned peaks are of, C order."""
        if self._peak_arrays is None:
            self._peak_arrays = tuple(np.ascontiguousarray(values) for values in (
                self.times, self.velocity, self.acceleration, self.jerk, self.qdot, self.qddot))
        return self._peak_arrays

    def states(self, times, low=None, high=None):
        """
        Return times and exact joint states of knots wanted at ``times`` (K,).

        Each knot goes to the sample nearest to its time if that sample lies in
        the middle half of its cell, between ``low`` and ``high`` (arrays
        (K,)); without them, only to a sample within ``_SAME_TIME`` of the
        duration of it. Where there is none the motion is evaluated at the
        wanted time itself.

        Returns
        -------
        tuple of numpy.ndarray
            (times (K,), q, q_dot, q_ddot (K, 3)).

        """
        times = np.ascontiguousarray(times, dtype=float)
        nearest, usable = self._nearest(times, low, high)
        result_times = np.where(usable, self.times[nearest], times)
        q = joint_angles(self.cos_q[nearest], self.sin_q[nearest])
        qdot, qddot = self.qdot[nearest], self.qddot[nearest]
        if not usable.all():
            missing = ~usable
            q[missing], qdot[missing], qddot[missing] = _joint_states(
                self.motion, self.geometry, times[missing])
        return result_times, q, qdot, qddot

    def tcp_positions(self, times):
        """Return the planned TCP positions at ``times`` (K,), of samples where there are."""
        times = np.ascontiguousarray(times, dtype=float)
        nearest, same = self._nearest(times)
        position = self.position[nearest]
        if not same.all():
            position[~same] = _checked_state_at(self.motion, times[~same])[0]
        return position

    def _nearest(self, times, low=None, high=None):
        """Return :func:`_nearest_samples` of ``times`` (K,) (the rule of :meth:`states`)."""
        nearest = np.empty(times.size, np.int64)
        usable = np.empty(times.size, np.bool_)
        bounds = (_NO_BOUNDS, _NO_BOUNDS) if low is None else (
            np.ascontiguousarray(low, dtype=float), np.ascontiguousarray(high, dtype=float))
        _nearest_samples(self.times, times, *bounds, _SAME_TIME * self.duration, nearest,
                         usable)
        return nearest, usable

    def planned(self, times):
        """
        Return the planned positions at ``times`` (N,) [s], shape (N, 3) [m].

        Interpolated between the samples by the cubic through position and
        velocity at both ends: its error is at most a jerk step times h**3 / 96
        for samples h apart, about 1e-9 m at 0.2 ms, a ten-thousandth of the
        tolerances it serves (``_PLANNED_TABLE_MIN_TOLERANCE`` and up).
        """
        table_times, position, velocity = self.planned_table()
        rows = np.empty((times.size, 3))
        _hermite_rows(table_times, position, velocity, np.ascontiguousarray(times), rows)
        return rows

    def planned_table(self):
        """Return the table :meth:`planned` interpolates: times (K,), positions, velocities."""
        if self._planned is None:
            # Of two samples at the same time (both sides of a step), the later one. Stored as
            # coordinate rows (3, K): the products with the per-point basis (N,) then run
            # along the points, not across 3 coordinates.
            self._planned = _distinct_samples(self.times, self.position, self.velocity,
                                              _SAME_TIME * self.duration)
        return self._planned


@kernel
def _distinct_samples(times, position, velocity, same):
    """
    Return the samples' times (K,), positions and velocities (3, K) without near repeats.

    A sample at most ``same`` before the next one is left out (of two at one time, the
    later stays), except the first; the last always stays.
    """
    count = times.size
    index = np.empty(count, np.int64)
    kept = 0
    for row in range(count):
        if row == 0 or row == count - 1 or times[row + 1] - times[row] > same:
            index[kept] = row
            kept += 1
    table_times = np.empty(kept)
    rows = np.empty((3, kept))
    rates = np.empty((3, kept))
    for column in range(kept):
        row = index[column]
        table_times[column] = times[row]
        for axis in range(3):
            rows[axis, column] = position[row, axis]
            rates[axis, column] = velocity[row, axis]
    return table_times, rows, rates


@kernel
def _interval_peaks(sample_times, velocity, acceleration, jerk, qdot, qddot, times, peaks):
    """
    Fill ``peaks`` (K - 1, 5) with :meth:`MotionSamples.segment_peaks` on ``times`` (K,).

    Of the samples at ``sample_times`` (N,) with TCP velocity, acceleration, jerk and joint
    rates (N, 3) (:meth:`MotionSamples._peak_source`).
    """
    source = (sample_times, velocity, acceleration, jerk, qdot, qddot)
    for interval in range(times.size - 1):
        _interval_peak(source, times[interval], times[interval + 1], peaks, interval)


@kernel
def _segments_beyond(sample_times, velocity, acceleration, jerk, qdot, qddot, times, table,
                     bounds, share):
    """Return :meth:`MotionSamples.segments_beyond` (the samples as :func:`_interval_peaks`)."""
    source = (sample_times, velocity, acceleration, jerk, qdot, qddot)
    found = np.empty(table.shape[0], np.int64)
    count = 0
    peaks = np.empty((1, 5))
    for segment in range(table.shape[0]):
        beyond = False
        for key in range(5):
            beyond = beyond or table[segment, key] > bounds[key]
        if not beyond:
            continue
        _interval_peak(source, times[segment], times[segment + 1], peaks, 0)
        for key in range(5):
            if table[segment, key] > bounds[key] and table[segment, key] > share * peaks[0, key]:
                found[count] = segment
                count += 1
                break
    return found[:count].copy()


@kernel(inline=True)
def _interval_peak(source, start, end, peaks, row):
    """
    Fill ``peaks[row]`` with the largest of each quantity of the samples from start to end.

    The samples from the first at or after ``start`` to the last at or before ``end``, at
    least one (the one at ``start``, the last if none follows); ``source`` holds the
    arguments of :func:`_interval_peaks` that are the samples'.
    """
    sample_times, velocity, acceleration, jerk, qdot, qddot = source
    count = sample_times.size
    first = np.searchsorted(sample_times, start)
    last = max(np.searchsorted(sample_times, end, side='right'), first + 1)
    for key in range(5):
        peaks[row, key] = 0.0
    for sample in range(first, last):
        at = min(sample, count - 1)
        values = (_norm(_row(velocity, at)), _norm(_row(acceleration, at)),
                  _norm(_row(jerk, at)), _largest_magnitude(_row(qdot, at)),
                  _largest_magnitude(_row(qddot, at)))
        for key in range(5):
            peaks[row, key] = max(peaks[row, key], values[key])


@kernel(inline=True)
def _largest_magnitude(vector):
    """Return the largest magnitude of the entries of a 3-tuple."""
    return max(abs(vector[0]), abs(vector[1]), abs(vector[2]))


@kernel(inline=True)
def _sorted_position(sorted_values, target, start):
    """
    Return ``np.searchsorted(sorted_values, target)``, knowing the values before ``start`` lower.

    A short walk from ``start`` (a search continued from a lower target), else a binary
    search from there; NumPy's own search for a NaN target.
    """
    if target != target:
        return np.searchsorted(sorted_values, target)
    low, high = start, sorted_values.size
    for _ in range(_WALK_STEPS):
        if low == high or not sorted_values[low] < target:
            return low
        low += 1
    while low < high:
        middle = (low + high) // 2
        if sorted_values[middle] < target:
            low = middle + 1
        else:
            high = middle
    return low


@kernel
def _hermite_rows(table_times, position, velocity, times, rows):
    """Fill ``rows`` (N, 3) with :func:`_hermite_row` at each of ``times`` (N,)."""
    for row in range(times.size):
        _hermite_row(table_times, position, velocity, times[row], rows, row)


@kernel
def _hermite_row(table_times, position, velocity, time, rows, row):
    """
    Write the cubic Hermite interpolation of the table at ``time`` into ``rows[row]``.

    ``position`` and ``velocity`` are coordinate rows (3, K) at ``table_times`` (K,);
    the interval is the last one starting at or before t (the first or last beyond).
    """
    final = table_times.size - 2
    step = min(max(np.searchsorted(table_times, time, side='right') - 1, 0), final)
    _hermite_in(table_times, position, velocity, step, time, rows, row)


@kernel
def _hermite_in(table_times, position, velocity, step, time, rows, row):
    """:func:`_hermite_row` on the table's interval ``step`` (the search already done)."""
    after = step + 1
    start = table_times[step]
    width = table_times[after] - start
    x = (time - start) / width
    x2, x3 = x * x, x * x * x
    # Cubic Hermite basis on [0, 1]; the velocities scale with the width.
    for axis in range(3):
        rows[row, axis] = ((2.0 * x3 - 3.0 * x2 + 1.0) * position[axis, step]
                           + (x3 - 2.0 * x2 + x) * width * velocity[axis, step]
                           + (3.0 * x2 - 2.0 * x3) * position[axis, after]
                           + (x3 - x2) * width * velocity[axis, after])


# No cell bounds: _nearest_samples takes only samples at the wanted time.
_NO_BOUNDS = np.empty(0)


@kernel
def _nearest_samples(sorted_times, targets, low, high, same, nearest, usable):
    """
    Fill ``nearest`` (K,) with the sample of ``sorted_times`` nearest to each of ``targets``.

    ``usable`` (K,) tells whether a knot wanted at the target may sit there: the sample is
    in the middle half of the target's cell [``low``, ``high``] (arrays (K,)), or, without
    them (size 0), within ``same`` of the target.
    """
    last = sorted_times.size - 1
    position = 0
    for row in range(targets.size):
        target = targets[row]
        # Targets in order (as a rule) continue the search where the one before ended.
        position = _sorted_position(sorted_times, target,
                                    position if row > 0 and targets[row - 1] <= target else 0)
        index = min(max(position, 1), last)
        closer_before = target - sorted_times[index - 1] <= sorted_times[index] - target
        nearest[row] = index - 1 if closer_before else index
        moved = sorted_times[nearest[row]]
        if low.size == 0:
            usable[row] = abs(moved - target) <= same
        else:
            usable[row] = (moved - low[row] >= 0.5 * (target - low[row])
                           and high[row] - moved >= 0.5 * (high[row] - target))


def check_joint_limits(traj, geometry, joint_limits, *, samples_per_segment=0, table=None):
    """
    Raise :class:`LimitError` at the first sample that breaks a joint limit.

    Checks ``joint_min <= q <= joint_max``, ``|q_dot| <= max_velocity`` and
    ``|q_ddot| <= max_acceleration`` at every point of ``traj``, in time order (position,
    then velocity, then acceleration; joints in order at one sample).

    Parameters
    ----------
    traj : JointTrajectoryData
        Densely sampled trajectory, or knots.
    geometry : DeltaGeometry
        Gives the joint position limits.
    joint_limits : JointLimits
        Velocity and acceleration limits.
    samples_per_segment : int
        If > 0, also check JTC's quintic interpolation at this many interior points of every
        segment (use it for knots: the polynomial may peak between them).
    table : numpy.ndarray, optional
        The executed peaks of ``traj`` (:func:`executed_table`, (K - 1, 5)), with the
        exact joint speed and acceleration extremes of each segment's quintic. Then only
        the segments that could break a limit are walked as above: those whose extremes
        break one, or whose positions could reach a bound (their ends, widened by the
        largest speed times half the segment's length). A speed or acceleration extreme
        above its limit that the walk's samples miss is named at its own time.

    Raises
    ------
    LimitError
        Naming the joint, the quantity, the bound, the value and its time.

    """
    extra = int(require_range('samples_per_segment', samples_per_segment, 0.0))
    low, high = geometry.joint_min, geometry.joint_max
    vmax, amax = joint_limits.max_velocity, joint_limits.max_acceleration
    times = traj.time_from_start
    segments = max(times.size - 1, 0)
    if table is None:
        table = _NO_TABLE_ROWS
    elif np.shape(table) != (segments, len(EXECUTED_KEYS)):
        raise InvalidInputError(f'table: expected shape ({segments}, {len(EXECUTED_KEYS)}) '
                                f'(one row per segment), got shape {np.shape(table)}')
    table = np.ascontiguousarray(table, dtype=float)
    found = np.empty(2)
    quantity, joint = _joint_limit_rows(times, traj.positions, traj.velocities,
                                        traj.accelerations, extra, table, low, high, vmax,
                                        amax, found)
    if quantity < 0:
        return
    name = traj.joint_names[joint]
    when = f'at t={found[0]:.6g} s'
    if quantity == 0:
        raise LimitError(f'{name} position: expected a value in [{low:g}, {high:g}] rad, got '
                         f'{found[1]:.6g} {when}')
    if quantity == 1:
        raise LimitError(f'{name} velocity: expected |q\u0307| \u2264 {vmax:g} rad/s, got '
                         f'{found[1]:.6g} {when}')
    raise LimitError(f'{name} acceleration: expected |q\u0308| \u2264 {amax:g} rad/s^2, got '
                     f'{found[1]:.6g} {when}')


# No executed table: check_joint_limits walks every segment.
_NO_TABLE_ROWS = np.empty((0, 5))


@kernel
def _joint_limit_rows(times, positions, velocities, accelerations, extra, table, low, high,
                      vmax, amax, found):
    """
    Return (quantity, joint) of the first joint-limit violation of :func:`check_joint_limits`.

    With ``extra`` > 0 JTC's quintic of every segment is checked at its start and
    ``extra`` interior points, evenly spaced, then the last point; else the points. With a
    ``table`` (K - 1, 5) (none: 0 rows) only the segments it lets break a limit are
    walked; one whose speed or acceleration extreme breaks a limit between the samples
    is named at that extreme (:func:`_joint_peak`). Quantity 0 is the position, 1 the
    velocity, 2 the acceleration, -1 none; ``found`` receives its time and value.
    """
    c = np.empty((6, 3))
    state = np.empty((3, 3))
    count = times.size
    interpolated = extra > 0 and count > 1
    for segment in range(count - 1 if interpolated else 0):
        exceeded = False
        if table.shape[0] > 0:
            exceeded = table[segment, 3] > vmax or table[segment, 4] > amax
            # Within a segment a joint moves at most its largest speed times half the length
            # away from the nearer end.
            reach = 0.5 * table[segment, 3] * (times[segment + 1] - times[segment])
            near = False
            for j in range(3):
                first, second = positions[segment, j], positions[segment + 1, j]
                near = near or max(first, second) + reach > high or (
                    min(first, second) - reach < low)
            if not (exceeded or near):
                continue
        length = times[segment + 1] - times[segment]
        _fill_quintic(length, positions, positions, velocities, velocities, accelerations,
                      accelerations, segment, segment + 1, c)
        for sample in range(extra + 1):
            x = length * (sample / (extra + 1.0))
            for derivative in range(3):
                for j in range(3):
                    state[derivative, j] = _polynomial(c, j, x, derivative)
            quantity, joint = _limit_broken(state, low, high, vmax, amax)
            if quantity >= 0:
                found[0], found[1] = times[segment] + x, state[quantity, joint]
                return quantity, joint
        if exceeded:
            # Its extreme lies between the samples: the first offence, named where it is.
            quantity = 1 if table[segment, 3] > vmax else 2
            value, offset, joint = _joint_peak(c, length, quantity)
            found[0], found[1] = times[segment] + offset, value
            return quantity, joint
    for point in range(count - 1 if interpolated else 0, count):
        for j in range(3):
            state[0, j], state[1, j] = positions[point, j], velocities[point, j]
            state[2, j] = accelerations[point, j]
        quantity, joint = _limit_broken(state, low, high, vmax, amax)
        if quantity >= 0:
            found[0], found[1] = times[point], state[quantity, joint]
            return quantity, joint
    return -1, 0


@kernel
def _limit_broken(state, low, high, vmax, amax):
    """Return (quantity, joint) of the first limit ``state`` (q; q_dot; q_ddot) breaks."""
    for j in range(3):
        if state[0, j] < low or state[0, j] > high:
            return 0, j
    for j in range(3):
        if abs(state[1, j]) > vmax:
            return 1, j
    for j in range(3):
        if abs(state[2, j]) > amax:
            return 2, j
    return -1, 0


def segment_polynomials(traj):
    """
    Return JTC's quintic of every segment, coefficients in powers of ``t - t_k``, (K-1, 6, 3).

    Evaluate one with :func:`evaluate_segments`; a segment's polynomial extends
    beyond its ends, which gives one-sided derivatives at the knots.
    """
    count = traj.time_from_start.size
    index = np.arange(count - 1)
    return _quintic_coefficients(traj, index, index + 1)


def evaluate_segments(coefficients, offset, derivatives=True):
    """
    Return position, velocity, acceleration and jerk of polynomials (S, 6, 3) at (S, M).

    Each is of shape (S, M, 3): joint angle [rad] and its time derivatives; only the
    positions if not ``derivatives``.
    """
    if not derivatives:
        return _evaluate(coefficients, offset, 0)[0]
    return _evaluate(coefficients, offset, 3)


def knots_at(motion, geometry, times, joint_names=DEFAULT_JOINT_NAMES):
    """Return the exact joint states of ``motion`` at increasing ``times`` (N,) as knots."""
    times = np.asarray(times, dtype=float)
    q, qdot, qddot = _joint_states(motion, geometry, times)
    return JointTrajectoryData(_names(joint_names), times, q, qdot, qddot)


def executed_peaks(trajectory, geometry):
    """
    Return the peaks of what JTC executes: its quintic through ``trajectory``, through FK.

    TCP speed [m/s], acceleration norm [m/s^2] and jerk norm [m/s^3] are the exact
    derivatives of the forward kinematics of each segment's own polynomial
    (:func:`~ellipath_ros.core.kinematics.tcp_derivatives`), so the one-sided values
    at every knot count (JTC's jerk steps there); joint speed and acceleration are the
    polynomials' derivatives. See :func:`executed_table` for the sampling.

    Returns
    -------
    dict
        ``EXECUTED_KEYS`` -> float.

    """
    if trajectory.time_from_start.size < 2:
        return dict.fromkeys(EXECUTED_KEYS, 0.0)
    peaks = executed_table(trajectory, geometry).max(axis=0)
    return {key: float(value) for key, value in zip(EXECUTED_KEYS, peaks)}


def executed_table(trajectory, geometry, previous=None):
    """
    Return the executed peaks of every segment (S, 5), ``EXECUTED_KEYS`` order.

    The joint speed and acceleration are exact: the extremes of each quintic's
    derivatives, at the ends and where the next derivative vanishes
    (:func:`_joint_extremes`). The TCP speed, acceleration and jerk of each
    segment are sampled ``_EXECUTED_SAMPLES`` + 1 times (ends included), and
    each quantity's largest sample is refined by a parabola through it and its
    neighbours, evaluated exactly at its vertex. In the segments within
    ``_EXECUTED_REFINE_SHARE`` of a quantity's largest peak, every local
    maximum of its samples above that share is then searched for the true
    maximum (:func:`_peak_rows`): the reported peak of the trajectory is the
    maximum, not a sample of it. ``previous`` = (knot times, table) of an
    earlier set of knots: segments it has (same start, same end) are taken
    from it (and searched again where they are near a largest peak: cheap, and
    the table stays exact whichever knots follow).
    """
    times = trajectory.time_from_start
    table = np.zeros((times.size - 1, len(EXECUTED_KEYS)))
    todo = np.ones(times.size - 1, bool)
    if times.size < 2:
        return table
    if previous is not None:
        old_times, old_table = previous
        start = np.minimum(np.searchsorted(old_times, times[:-1]), old_times.size - 2)
        same = (old_times[start] == times[:-1]) & (old_times[start + 1] == times[1:])
        table[same] = old_table[start[same]]
        todo = ~same
        if same.all():
            return table
    failed_offset = np.empty(1)
    failed = _peak_rows(times, trajectory.positions, trajectory.velocities,
                        trajectory.accelerations, todo, _EXECUTED_SAMPLES,
                        _EXECUTED_REFINE_SHARE, *_kernel_geometry(geometry), table,
                        failed_offset)
    if failed >= 0:
        # The error of the first pose that cannot be assembled, named as before.
        q, qdot, qddot, qdddot = evaluate_segments(
            _quintic_coefficients(trajectory, np.array([failed]), np.array([failed + 1])),
            failed_offset.reshape(1, 1))
        tcp_derivatives(q.reshape(-1, 3), qdot.reshape(-1, 3), qddot.reshape(-1, 3),
                        qdddot.reshape(-1, 3), geometry, name='interpolated q')
    return table


@kernel
def _peak_rows(times, positions, velocities, accelerations, todo, samples, share, rx, ry,
               offset, upper, forearm_sq, coplanar, table, failed_offset):
    """
    Fill the rows ``todo`` of ``table`` (S, 5) with the executed peaks; return a failed one.

    Each segment's quintic (:func:`_fill_quintic` of the points ``times`` (S + 1,),
    ``positions``, ``velocities``, ``accelerations`` (S + 1, 3), built where it is
    evaluated) gives its exact joint peaks (:func:`_joint_extremes`); its TCP speed,
    acceleration and jerk are evaluated at ``samples`` + 1 evenly spaced offsets, ends
    included, and each quantity's largest sample is refined by the parabola through it and
    its neighbours (the middle one of three at a segment end), evaluated at its vertex.
    Then, in every segment (``todo`` or not) whose peak of a quantity is within ``share`` of the
    column's largest, every local maximum of that quantity's samples above that share
    (the _EXECUTED_CANDIDATES largest) is searched for the maximum between its two
    neighbours (:func:`_search_peak`). A pose that cannot be assembled (or is coplanar)
    stops the pass: its segment is returned, its offset in ``failed_offset[0]``; -1 when
    all are assembled.
    """
    count = times.size - 1
    lengths = np.empty(count)
    for segment in range(count):
        lengths[segment] = times[segment + 1] - times[segment]
    values = np.empty((count, samples + 1, 3))
    c = np.empty((6, 3))
    for segment in range(count):
        if not todo[segment]:
            continue
        _fill_quintic(lengths[segment], positions, positions, velocities, velocities,
                      accelerations, accelerations, segment, segment + 1, c)
        table[segment, 3], table[segment, 4] = _joint_extremes(c, lengths[segment])
        if not _sample_segment(c, lengths[segment], samples, rx, ry, offset, upper, forearm_sq,
                               coplanar, values[segment], failed_offset):
            return segment
        for key in range(3):
            state, peak, where = _parabola_peak(c, lengths[segment] / samples, samples,
                                                values[segment], key, rx, ry, offset, upper,
                                                forearm_sq, coplanar)
            if state != _ASSEMBLED:
                failed_offset[0] = where
                return segment
            table[segment, key] = peak
    floors = np.empty(3)
    for key in range(3):
        floors[key] = (1.0 - share) * table[:, key].max()
    chosen = np.empty(_EXECUTED_CANDIDATES, np.int64)
    for segment in range(count):
        if not (table[segment, 0] >= floors[0] or table[segment, 1] >= floors[1]
                or table[segment, 2] >= floors[2]):
            continue
        _fill_quintic(lengths[segment], positions, positions, velocities, velocities,
                      accelerations, accelerations, segment, segment + 1, c)
        step = lengths[segment] / samples
        if not (todo[segment] or _sample_segment(c, lengths[segment], samples, rx, ry, offset,
                                                 upper, forearm_sq, coplanar, values[segment],
                                                 failed_offset)):
            return segment
        for key in range(3):
            if table[segment, key] < floors[key]:
                continue
            found = _local_maxima(values[segment], key, floors[key], chosen)
            for candidate in range(found):
                state, peak, where = _search_peak(c, chosen[candidate], step, samples,
                                                  values[segment], key, rx, ry, offset, upper,
                                                  forearm_sq, coplanar)
                if state != _ASSEMBLED:
                    failed_offset[0] = where
                    return segment
                table[segment, key] = max(table[segment, key], peak)
    return -1


@kernel
def _sample_segment(c, length, samples, rx, ry, offset, upper, forearm_sq, coplanar, values,
                    failed_offset):
    """
    Fill ``values`` (samples + 1, 3) with TCP speed, acceleration, jerk along quintic ``c``.

    Evenly spaced, ends included. Returns whether every pose is assembled; if not, the
    offset of the first that is not goes to ``failed_offset[0]`` (the rest is not filled).
    """
    for sample in range(samples + 1):
        x = length * (sample / samples)
        state, speed, accel, jerk = _executed_tcp(c, x, 3, rx, ry, offset, upper, forearm_sq,
                                                  coplanar)
        if state != _ASSEMBLED:
            failed_offset[0] = x
            return False
        values[sample, 0], values[sample, 1], values[sample, 2] = speed, accel, jerk
    return True


@kernel
def _parabola_peak(c, step, samples, values, key, rx, ry, offset, upper, forearm_sq,
                   coplanar):
    """
    Return (status, peak, offset): quantity ``key``'s largest sample, refined by a parabola.

    The parabola through the largest sample and its neighbours (the middle one of three
    at a segment end) is evaluated exactly at its vertex; the larger of the two counts.
    """
    largest = 0
    for sample in range(1, samples + 1):
        if values[sample, key] > values[largest, key]:
            largest = sample
    centre = min(max(largest, 1), samples - 1)
    before, middle, after = (values[centre - 1, key], values[centre, key],
                             values[centre + 1, key])
    curvature = before - 2.0 * middle + after
    shift = 0.5 * (before - after) / curvature if curvature < 0.0 else 0.0
    vertex = min(max(centre + shift, 0.0), float(samples)) * step
    state, found = _executed_value(c, vertex, key, rx, ry, offset, upper, forearm_sq, coplanar)
    return state, max(values[largest, key], found), vertex


@kernel
def _local_maxima(values, key, floor, chosen):
    """
    Put the largest local maxima of column ``key`` of ``values`` at or above ``floor`` in chosen.

    A sample is a local maximum when no neighbour is larger (the ends have one); at most
    ``chosen.size``, largest first. Returns how many.
    """
    last = values.shape[0] - 1
    count = 0
    for sample in range(last + 1):
        value = values[sample, key]
        if value < floor or (sample > 0 and values[sample - 1, key] > value) or (
                sample < last and values[sample + 1, key] > value):
            continue
        # Insertion into the sorted list of at most chosen.size.
        place = count
        while place > 0 and values[chosen[place - 1], key] < value:
            place -= 1
        if place >= chosen.size:
            continue
        for moved in range(min(count, chosen.size - 1), place, -1):
            chosen[moved] = chosen[moved - 1]
        chosen[place] = sample
        count = min(count + 1, chosen.size)
    return count


@kernel
def _search_peak(c, centre, step, samples, values, key, rx, ry, offset, upper, forearm_sq,
                 coplanar):
    """
    Return (status, maximum, offset) of quantity ``key`` around sample ``centre``.

    Brent's minimisation (golden sections and parabolic steps) of the negated quantity
    on the sample's two neighbouring intervals, seeded with the three samples, down to
    ``_EXECUTED_SEARCH_TOLERANCE`` of a sample interval: near a smooth maximum the value
    missed is quadratic in that distance. The status is that of the first pose that
    cannot be assembled, if any (the search stops there).
    """
    low = max(centre - 1, 0) * step
    high = min(centre + 1, samples) * step
    x = centre * step
    best = values[centre, key]
    # The neighbours seed the first parabolic step.
    before = values[max(centre - 1, 0), key]
    after = values[min(centre + 1, samples), key]
    w, fw = (low, -before) if before >= after else (high, -after)
    v, fv = (high, -after) if before >= after else (low, -before)
    fx = -best
    tolerance = _EXECUTED_SEARCH_TOLERANCE * step
    moved = high - low
    d = 0.0
    for _ in range(_EXECUTED_SEARCH_STEPS):
        middle = 0.5 * (low + high)
        if abs(x - middle) <= 2.0 * tolerance - 0.5 * (high - low):
            break
        p = q = r = 0.0
        if abs(moved) > tolerance:
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            else:
                q = -q
            r = moved
            moved = d
        if abs(p) < abs(0.5 * q * r) and p > q * (low - x) and p < q * (high - x):
            d = p / q
            u = x + d
            if u - low < 2.0 * tolerance or high - u < 2.0 * tolerance:
                d = tolerance if x < middle else -tolerance
        else:
            moved = (high - x) if x < middle else (low - x)
            d = _GOLDEN_SECTION * moved
        u = x + (d if abs(d) >= tolerance else (tolerance if d > 0.0 else -tolerance))
        state, found = _executed_value(c, u, key, rx, ry, offset, upper, forearm_sq, coplanar)
        if state != _ASSEMBLED:
            return state, best, u
        fu = -found
        if fu <= fx:
            if u < x:
                high = x
            else:
                low = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                low = u
            else:
                high = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
    return _ASSEMBLED, -fx, x


@kernel
def _joint_extremes(c, length):
    """Return the largest |q_dot| and |q_ddot| of quintic ``c`` (6, 3) on [0, ``length``]."""
    return abs(_joint_peak(c, length, 1)[0]), abs(_joint_peak(c, length, 2)[0])


@kernel
def _joint_peak(c, length, derivative):
    """
    Return (value, offset, joint) of the largest |q_dot| (``derivative`` 1) or |q_ddot| (2).

    Of quintic ``c`` (6, 3) on [0, ``length``]; the signed value, where it is, and the
    joint. Exact: |q_ddot| (a cubic) peaks at an end or where q_dddot (a quadratic)
    vanishes; |q_dot| at an end or where q_ddot vanishes, found by bisection on each
    stretch between those points, where q_ddot is monotonic.
    """
    value, offset, joint = 0.0, 0.0, 0
    for j in range(3):
        first, second = _quadratic_roots(60.0 * c[5, j], 24.0 * c[4, j], 6.0 * c[3, j])
        cuts = (0.0, min(max(first, 0.0), length), min(max(second, 0.0), length), length)
        for cut in cuts:
            here = _polynomial(c, j, cut, derivative)
            if abs(here) > abs(value):
                value, offset, joint = here, cut, j
        for piece in range(3 if derivative == 1 else 0):
            low, high = cuts[piece], cuts[piece + 1]
            at_low, at_high = _polynomial(c, j, low, 2), _polynomial(c, j, high, 2)
            if high <= low or (at_low > 0.0) == (at_high > 0.0):
                continue
            for _ in range(_BISECTIONS):
                middle = 0.5 * (low + high)
                if (_polynomial(c, j, middle, 2) > 0.0) == (at_low > 0.0):
                    low = middle
                else:
                    high = middle
            here = _polynomial(c, j, 0.5 * (low + high), 1)
            if abs(here) > abs(value):
                value, offset, joint = here, 0.5 * (low + high), j
    return value, offset, joint


@kernel
def _quadratic_roots(a, b, c):
    """Return the real roots of ``a x^2 + b x + c`` in increasing order (inf where none)."""
    if a == 0.0:
        root = -c / b if b != 0.0 else np.inf
        return root, np.inf
    discriminant = b * b - 4.0 * a * c
    if discriminant < 0.0:
        return np.inf, np.inf
    # The root without cancellation, then the other from their product.
    half = -0.5 * (b + math.copysign(math.sqrt(discriminant), b))
    first = half / a
    second = c / half if half != 0.0 else first
    return min(first, second), max(first, second)


@kernel(inline=True)
def _executed_tcp(c, x, order, rx, ry, offset, upper, forearm_sq, coplanar):
    """
    Return (status, TCP speed, acceleration, jerk norm) of quintic ``c`` (6, 3) at ``x``.

    :func:`~ellipath_ros.core.kinematics._tcp_state` of the quintic's joint position and
    derivatives; derivatives above ``order`` (1 to 3) are not computed (0).
    """
    state, _, velocity, acceleration, jerk = _tcp_state(
        (_polynomial(c, 0, x, 0), _polynomial(c, 1, x, 0), _polynomial(c, 2, x, 0)),
        (_polynomial(c, 0, x, 1), _polynomial(c, 1, x, 1), _polynomial(c, 2, x, 1)),
        (_polynomial(c, 0, x, 2), _polynomial(c, 1, x, 2), _polynomial(c, 2, x, 2)),
        (_polynomial(c, 0, x, 3), _polynomial(c, 1, x, 3), _polynomial(c, 2, x, 3)),
        rx, ry, offset, upper, forearm_sq, coplanar, order)
    return state, _norm(velocity), _norm(acceleration), _norm(jerk)


@kernel(inline=True)
def _executed_value(c, x, key, rx, ry, offset, upper, forearm_sq, coplanar):
    """Return (status, value) of TCP quantity ``key`` (0 speed, 1 acceleration, 2 jerk)."""
    state, speed, accel, jerk = _executed_tcp(c, x, key + 1, rx, ry, offset, upper,
                                              forearm_sq, coplanar)
    return state, (speed, accel, jerk)[key]


@kernel
def _norm(vector):
    """Return the Euclidean norm of a 3-tuple."""
    return math.sqrt(vector[0] * vector[0] + vector[1] * vector[1] + vector[2] * vector[2])
