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
Emulation of ros2_control's joint_trajectory_controller (JTC) on ROS 2 Jazzy, without ROS.

What a robot executes is not the published trajectory but what JTC makes of it. This module
replays received ``trajectory_msgs/JointTrajectory`` messages through the logic of
ros-controls/ros2_controllers, branch ``jazzy``, ``joint_trajectory_controller``:

* ``JointTrajectoryController::update()`` (src/joint_trajectory_controller.cpp, about lines
  273-315): a message that arrived since the last cycle replaces the running trajectory at
  the next control cycle, whatever its ``header.stamp``. At its first sample
  ``set_point_before_trajectory_msg(time, state_current_)`` stores the measured state:
  position, velocity if the hardware has a velocity state interface, no acceleration.
  Each cycle at time T writes the command ``sample(T + period)``.
* ``Trajectory::sample()`` (src/trajectory.cpp, about lines 148-168): stamp 0 means "the
  time of the first sample"; before ``stamp + time_from_start[0]`` each joint is splined
  from the stored state (at the pickup time) to the first point; from there, segment
  ``[t_i, t_(i+1))`` uses ``interpolate_between_points`` (quintic with positions, velocities
  and accelerations; cubic with positions and velocities; linear with positions only; zero
  output for positions and accelerations without velocities, see
  :func:`~ellipath_ros.core.joint_trajectory.interpolation_coefficients`); after the last
  point the last point is held. A stamp in the past starts mid-trajectory (a jump).
* ``validate_trajectory_msg``: a non-zero stamp whose end lies before the reception time,
  a final velocity above FLT_EPSILON, times that do not increase or unknown joints are
  rejected at reception; the running trajectory is kept.

Assumptions: perfect tracking (the measured state at a cycle is the command written for it
by the cycle before), the nominal period every cycle (speed scaling 1), no acceleration state
interface, no path or goal tolerances, no action interface, no angle wrap-around, no
integration of missing positions (``allow_integration_in_goal_trajectories`` false), and
``interpolate_from_desired_state``/``open_loop_control`` off. Times are whole nanoseconds,
as ``rclcpp::Time`` and ``rclcpp::Duration`` are.

Arrays: times (N,) [s]; joint positions, velocities and accelerations (N, 3) [rad, rad/s,
rad/s^2], column i for the controller's joint i; TCP arrays (N, 3) [m] in the base frame.
"""

from dataclasses import dataclass
import math

from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import require_finite
from ellipath_ros.core.errors import require_range
from ellipath_ros.core.joint_trajectory import DEFAULT_JOINT_NAMES
from ellipath_ros.core.joint_trajectory import evaluate_polynomials
from ellipath_ros.core.joint_trajectory import interpolation_coefficients
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.joint_trajectory import TrajectoryRejectedError
from ellipath_ros.core.kinematics import forward_kinematics
import numpy as np

# JTC rejects a last point whose |velocity| exceeds std::numeric_limits<float>::epsilon().
FLT_EPSILON = float(np.finfo(np.float32).eps)
ALL_FIELDS = ('positions', 'velocities', 'accelerations')
_NS = 1_000_000_000


def _nanoseconds(seconds):
    """Whole nanoseconds of a time in seconds, as rclcpp converts it."""
    return int(round(seconds * _NS))


@dataclass(frozen=True, eq=False)
class ControllerSamples:
    """
    The commands the emulated controller wrote, one row per control cycle.

    Row k is the state commanded for time ``times[k]`` (written by the cycle one period
    before; row 0 is the state at ``start_time``). With perfect tracking it is also the
    measured state at that time.

    Attributes
    ----------
    times : numpy.ndarray, shape (N,)
        ``start_time + k * period`` [s].
    positions, velocities, accelerations : numpy.ndarray, shape (N, 3)
        Commanded joint positions [rad], velocities [rad/s], accelerations [rad/s^2].
    source : numpy.ndarray of int, shape (N,)
        Index (in reception order, accepted messages only) of the trajectory that commanded
        the row; -1 for the hold before the first one.
    pickup_times : numpy.ndarray, shape (M,)
        Time of the cycle that took up each accepted message [s]; NaN if another message
        replaced it before any cycle took it up, or none has run yet.
    period : float
        Control period [s].

    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    source: np.ndarray
    pickup_times: np.ndarray
    period: float

    def __post_init__(self):
        """Make the arrays read-only and check that their lengths agree."""
        count = np.shape(self.times)[0]
        for field in ('times', 'positions', 'velocities', 'accelerations', 'source',
                      'pickup_times'):
            array = np.array(getattr(self, field))
            if field != 'pickup_times' and array.shape[0] != count:
                raise InvalidInputError(
                    f'{field}: expected {count} rows (one per cycle), got {array.shape[0]}')
            array.setflags(write=False)
            object.__setattr__(self, field, array)


class _Active:
    """A received message in controller joint order, and its sampling state."""

    def __init__(self, index, message, stamp_ns, velocity_state):
        self.index = index
        self.knots_ns = message['knots_ns']
        self.positions = message['positions']
        self.velocities = message['velocities']
        self.accelerations = message['accelerations']
        self.velocity_state = velocity_state
        self.start_ns = stamp_ns  # trajectory_start_time_: 0 until the first sample
        self.before_ns = None
        self.before = None

    def take_up(self, time_ns, position, velocity):
        """``set_point_before_trajectory_msg`` and the first ``sample()`` at ``time_ns``."""
        if self.start_ns == 0:
            self.start_ns = time_ns
        self.before_ns = time_ns
        # The stored state has a velocity if the hardware reports one, or zeros if only the
        # message has velocities; acceleration is never measured (no acceleration state
        # interface), so it is zero when the message has accelerations.
        has_velocity = self.velocities is not None
        if self.velocity_state:
            before_velocity = velocity.copy()
        else:
            before_velocity = np.zeros(3) if has_velocity else None
        before_acceleration = np.zeros(3) if self.accelerations is not None else None
        self.before = (position.copy(), before_velocity, before_acceleration)

    def sample(self, times_ns):
        """``Trajectory::sample`` at each of ``times_ns`` (>= the pickup time)."""
        count = times_ns.size
        positions, velocities, accelerations = (np.zeros((count, 3)) for _ in range(3))
        knots = self.start_ns + self.knots_ns
        before = times_ns < knots[0]
        if before.any():
            q0, v0, a0 = self.before
            # The degree follows the fields both ends have: the stored state has velocities
            # whenever the message has (zeros without a velocity state), so a velocity state
            # alone does not turn a positions-only message into a cubic.
            v0 = v0 if self.velocities is not None else None
            coefficients = interpolation_coefficients(
                [(knots[0] - self.before_ns) / _NS], q0[np.newaxis], self.positions[:1],
                None if v0 is None else v0[np.newaxis], _first(self.velocities),
                None if a0 is None else a0[np.newaxis], _first(self.accelerations))
            offset = (times_ns[before] - self.before_ns) / _NS
            values = evaluate_polynomials(coefficients, offset[np.newaxis])
            for array, value in zip((positions, velocities, accelerations), values):
                array[before] = value[0]
        after = times_ns >= knots[-1]
        inside = ~before & ~after
        if inside.any():
            segment = np.searchsorted(knots, times_ns[inside], side='right') - 1
            coefficients = interpolation_coefficients(
                (knots[segment + 1] - knots[segment]) / _NS,
                self.positions[segment], self.positions[segment + 1],
                *_ends(self.velocities, segment), *_ends(self.accelerations, segment))
            offset = (times_ns[inside] - knots[segment]) / _NS
            values = evaluate_polynomials(coefficients, offset[:, np.newaxis])
            for array, value in zip((positions, velocities, accelerations), values):
                array[inside] = value[:, 0]
        # Past the end JTC holds the last point; empty velocities/accelerations become 0.
        positions[after] = self.positions[-1]
        for array, source in ((velocities, self.velocities),
                              (accelerations, self.accelerations)):
            if source is not None:
                array[after] = source[-1]
        return positions, velocities, accelerations


def _first(values):
    """Return the first row of an optional (K, 3) array, as (1, 3), or None."""
    return None if values is None else values[:1]


def _ends(values, segment):
    """Rows ``segment`` and ``segment + 1`` of an optional (K, 3) array, or two Nones."""
    if values is None:
        return None, None
    return values[segment], values[segment + 1]


class JazzyJtcEmulator:
    """
    joint_trajectory_controller (Jazzy) fed by a topic, at a fixed period, tracking perfectly.

    Feed it messages in reception order with :meth:`receive`, advance it with
    :meth:`run_until`, read the commands with :meth:`samples`. Cycles run at
    ``start_time + k * period``; the cycle at T takes up the last message received in
    ``(T - period, T]`` (a later one overwrites an earlier one not yet taken up, as JTC's
    realtime buffer does) and writes the command for ``T + period``.

    Parameters
    ----------
    joint_names : sequence of str
        The controller's joints, in its order (3 unique names).
    period : float
        Control period [s], > 0 (1 kHz by default).
    velocity_state : bool
        Whether the hardware has a velocity state interface: if so the state stored at a
        trajectory's first sample carries the measured velocity, otherwise zero.
    start_time : float
        Time of cycle 0 [s], on the clock of the stamps and reception times.
    initial_positions : array_like, shape (3,)
        Joint positions held (at rest) before the first trajectory [rad].

    """

    def __init__(self, joint_names=DEFAULT_JOINT_NAMES, period=0.001, velocity_state=True,
                 start_time=0.0, initial_positions=(0.0, 0.0, 0.0)):
        names = tuple(joint_names)
        if len(names) != 3 or len(set(names)) != 3:
            raise InvalidInputError(f'joint_names: expected 3 unique names, got {names!r}')
        self.joint_names = names
        self.period = require_range('period', period, 0.0, 1.0, low_open=True, unit='s')
        self._period_ns = _nanoseconds(self.period)
        if self._period_ns < 1:
            raise InvalidInputError(f'period: expected at least 1 ns, got {period!r}')
        self.velocity_state = bool(velocity_state)
        self._start_ns = _nanoseconds(require_finite('start_time', start_time))
        position = np.array(initial_positions, dtype=float)
        if position.shape != (3,) or not np.isfinite(position).all():
            raise InvalidInputError(
                f'initial_positions: expected 3 finite joint angles, got {initial_positions!r}')
        # Commands of the cycles run so far: row k is the state commanded for cycle k.
        self._rows = [(np.array([0]), position[np.newaxis], np.zeros((1, 3)),
                       np.zeros((1, 3)), np.array([-1]))]
        self._cycle = 0  # next cycle to run; the state for it is the last row
        self._active = None
        self._pending = None
        self._pickups = []
        self._last_receive_ns = None

    @property
    def time(self):
        """Time of the next cycle to run [s]."""
        return (self._start_ns + self._cycle * self._period_ns) / _NS

    def receive(self, trajectory, stamp, receive_time, fields=ALL_FIELDS):
        """
        Deliver a message at ``receive_time`` [s]; it is taken up at the next cycle.

        Parameters
        ----------
        trajectory : JointTrajectoryData
            The message's joint names and points (names may be in any order, as JTC sorts
            them to its own).
        stamp : float
            ``header.stamp`` [s]; 0 starts the trajectory at the cycle that takes it up.
        receive_time : float
            When the subscription callback runs [s]: not before the previous reception nor
            before the cycles already run.
        fields : sequence of str
            The point fields the message carries: ``positions`` plus any of ``velocities``
            and ``accelerations`` (the others are empty in the message; their values in
            ``trajectory`` are ignored).

        Returns
        -------
        int
            Index of the message among the accepted ones (the ``source`` of its rows).

        Raises
        ------
        TrajectoryRejectedError
            JTC's ``validate_trajectory_msg`` would reject the message (it logs an error and
            keeps the running trajectory; so does the emulator).
        InvalidInputError
            Malformed arguments, or a reception time in the emulator's past.

        """
        if not isinstance(trajectory, JointTrajectoryData):
            raise InvalidInputError(
                f'trajectory: expected a JointTrajectoryData, got {type(trajectory).__name__}')
        fields = tuple(fields)
        if 'positions' not in fields or not set(fields) <= set(ALL_FIELDS):
            raise InvalidInputError(
                f'fields: expected positions plus any of velocities, accelerations, got '
                f'{fields!r}')
        stamp_ns = _nanoseconds(require_finite('stamp', stamp))
        receive_ns = _nanoseconds(require_finite('receive_time', receive_time))
        last_cycle_run_ns = self._start_ns + (self._cycle - 1) * self._period_ns
        if self._cycle > 0 and receive_ns <= last_cycle_run_ns:
            raise InvalidInputError(
                f'receive_time: expected a time after {last_cycle_run_ns / _NS:.9g} s (the '
                f'last cycle already run), got {receive_time!r}')
        if self._last_receive_ns is not None and receive_ns < self._last_receive_ns:
            raise InvalidInputError(
                f'receive_time: expected a time >= {self._last_receive_ns / _NS:.9g} s (the '
                f'previous reception), got {receive_time!r}')
        message = self._validate(trajectory, stamp_ns, receive_ns, fields)
        # Cycles before the reception run with what was there; the first cycle at or after
        # it takes the message up.
        self._run_to_cycle(self._cycle_at_or_after(receive_ns))
        self._last_receive_ns = receive_ns
        index = len(self._pickups)
        self._pickups.append(math.nan)
        self._pending = (index, message, stamp_ns)
        return index

    def _validate(self, trajectory, stamp_ns, receive_ns, fields):
        """``validate_trajectory_msg``; return the points in controller joint order."""
        unknown = [name for name in trajectory.joint_names if name not in self.joint_names]
        if unknown:
            raise TrajectoryRejectedError(
                f'joint_names: expected the controller joints {self.joint_names!r}, got '
                f'{trajectory.joint_names!r} (JTC: "Incoming joint {unknown[0]} doesn\'t '
                'match the controller\'s joints")')
        order = [trajectory.joint_names.index(name) for name in self.joint_names]
        if 'velocities' in fields:
            moving = np.abs(trajectory.velocities[-1]) > FLT_EPSILON
            if moving.any():
                joint = int(np.argmax(moving))
                raise TrajectoryRejectedError(
                    f'velocities[-1] of {trajectory.joint_names[joint]}: expected |v| <= '
                    f'{FLT_EPSILON:g} rad/s at the last point, got '
                    f'{trajectory.velocities[-1, joint]!r}')
        knots_ns = np.array([_nanoseconds(t) for t in trajectory.time_from_start],
                            dtype=np.int64)
        if knots_ns.size > 1 and (np.diff(knots_ns) <= 0).any():
            index = int(np.argmax(np.diff(knots_ns) <= 0)) + 1
            raise TrajectoryRejectedError(
                f'time_from_start[{index}]: expected a time after point {index - 1} in whole '
                f'nanoseconds, got {trajectory.time_from_start[index]!r} s')
        if stamp_ns != 0 and stamp_ns + knots_ns[-1] < receive_ns:
            raise TrajectoryRejectedError(
                f'header.stamp: expected 0 or a stamp whose end (stamp + '
                f'{knots_ns[-1] / _NS:g} s) is not before the reception at '
                f'{receive_ns / _NS:.9g} s, got {stamp_ns / _NS:.9g} s (JTC: "Received '
                'trajectory with non-zero start time ... that ends in the past")')
        return {
            'knots_ns': knots_ns,
            'positions': trajectory.positions[:, order],
            'velocities': (trajectory.velocities[:, order] if 'velocities' in fields
                           else None),
            'accelerations': (trajectory.accelerations[:, order] if 'accelerations' in fields
                              else None),
        }

    def _cycle_at_or_after(self, time_ns):
        """Index of the first cycle at or after ``time_ns``."""
        return max(0, -((self._start_ns - time_ns) // self._period_ns))

    def run_until(self, time):
        """
        Run every cycle up to ``time`` [s], so that :meth:`samples` reaches it.

        After this the samples cover every cycle time <= ``time`` (and no cycle has run that
        a message received at ``time`` should have been taken up by).
        """
        time_ns = _nanoseconds(require_finite('time', time))
        self._run_to_cycle((time_ns - self._start_ns) // self._period_ns)

    def _run_to_cycle(self, cycle):
        """Run cycles until the state for ``cycle`` is known (its own cycle not yet run)."""
        while self._cycle < cycle:
            if self._pending is not None:
                index, message, stamp_ns = self._pending
                self._pending = None
                self._active = _Active(index, message, stamp_ns, self.velocity_state)
                _, positions, velocities, _, _ = self._rows[-1]
                now_ns = self._start_ns + self._cycle * self._period_ns
                self._active.take_up(now_ns, positions[-1], velocities[-1])
                self._pickups[index] = now_ns / _NS
            # Between receptions the commands are one trajectory's samples: run them at once.
            cycles = np.arange(self._cycle + 1, cycle + 1)
            times_ns = self._start_ns + cycles * self._period_ns
            if self._active is None:
                hold = self._rows[0][1][0]
                values = (np.tile(hold, (cycles.size, 1)), np.zeros((cycles.size, 3)),
                          np.zeros((cycles.size, 3)))
                source = -1
            else:
                values = self._active.sample(times_ns)
                source = self._active.index
            self._rows.append((cycles, *values, np.full(cycles.size, source)))
            self._cycle = cycle

    def samples(self):
        """Return the commands of the cycles run so far, as :class:`ControllerSamples`."""
        cycles, positions, velocities, accelerations, source = (
            np.concatenate(column) for column in zip(*self._rows))
        return ControllerSamples(
            times=(self._start_ns + cycles * self._period_ns) / _NS, positions=positions,
            velocities=velocities, accelerations=accelerations, source=source,
            pickup_times=np.array(self._pickups, dtype=float), period=self.period)


@dataclass(frozen=True, eq=False)
class ExecutedTcp:
    """
    The TCP motion of commanded joint states (executed = what the controller commands).

    Attributes
    ----------
    times : numpy.ndarray, shape (N,)
        Sample times [s], equally spaced by ``period``.
    positions : numpy.ndarray, shape (N, 3)
        Exact forward kinematics of the commanded joint positions [m]; NaN where the joints
        cannot be assembled into a robot.
    peak_speed, peak_acceleration, peak_jerk : float
        Largest norm of the first, second and third finite differences of ``positions``
        divided by ``period``, ``period^2``, ``period^3`` [m/s, m/s^2, m/s^3]. At 1 kHz the
        differences are accurate to well under 1 % on the smooth parts; a jump in the
        command shows as a peak of the size the hardware would be asked for.

    """

    times: np.ndarray
    positions: np.ndarray
    peak_speed: float
    peak_acceleration: float
    peak_jerk: float


def executed_tcp(samples, geometry):
    """
    Forward kinematics and finite-difference peaks of a controller's commands.

    Parameters
    ----------
    samples : ControllerSamples
        The emulated commands.
    geometry : DeltaGeometry
        Robot dimensions.

    Returns
    -------
    ExecutedTcp

    """
    positions = forward_kinematics(samples.positions, geometry, strict=False)
    step = samples.period
    peaks = []
    for order in (1, 2, 3):
        if positions.shape[0] > order:
            norms = np.linalg.norm(np.diff(positions, order, axis=0), axis=1) / step ** order
            peaks.append(math.nan if np.isnan(norms).all() else float(np.nanmax(norms)))
        else:
            peaks.append(0.0)
    return ExecutedTcp(samples.times, positions, *peaks)


def planned_tcp_path(trajectory, geometry, step=5e-4):
    """
    TCP polyline of JTC's quintic interpolation of one trajectory on its own [m], (M, 3).

    This is the planned path as the controller would follow it had it nothing else to do:
    forward kinematics of :func:`quintic_interpolate` every ``step`` seconds (and at the
    end). A chord strays from the curve by at most ``a step^2 / 8`` with ``a`` the TCP's
    normal acceleration: 1.6 micrometres at 50 m/s^2 and the default 0.5 ms.
    """
    step = require_range('step', step, 0.0, low_open=True, unit='s')
    start, end = trajectory.time_from_start[0], trajectory.time_from_start[-1]
    count = max(2, int(math.ceil((end - start) / step)) + 1)
    q = quintic_interpolate(trajectory, np.linspace(start, end, count))[0]
    return forward_kinematics(q, geometry, name='interpolated q')


def distance_to_paths(points, paths, chunk=128, candidates=4):
    """
    Distance of each point to the nearest of several polylines [m], shape (N,).

    For each polyline the ``candidates`` vertices nearest to a point are found by brute force
    and the distance is measured to the two chords that meet at each of them; the smallest
    over all polylines is returned. Measuring each polyline on its own matters where two
    paths run close (a place and the lift out of it): the overall nearest vertex may belong
    to the other path while this one passes closer between two of its vertices. The result
    is exact when a nearest chord touches one of the candidates, which holds for chords short
    against the curvature radius, as :func:`planned_tcp_path` gives. NaN points give NaN.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Points [m].
    paths : sequence of array_like, each (M_j, 3)
        Polylines [m], each with at least 2 vertices.
    chunk : int
        Points handled per block (memory ~ chunk * vertices of a path * 8 bytes).
    candidates : int
        Nearest vertices examined per polyline, >= 1.

    """
    points = np.asarray(points, dtype=float)
    polylines = [np.asarray(path, dtype=float) for path in paths]
    if not polylines:
        raise InvalidInputError('paths: expected at least one polyline, got none')
    for path in polylines:
        if path.ndim != 2 or path.shape[0] < 2 or path.shape[1] != 3:
            raise InvalidInputError(
                f'paths: expected polylines of shape (M, 3) with M >= 2, got {path.shape}')
    distances = np.full(points.shape[0], math.nan)
    finite = np.flatnonzero(np.isfinite(points).all(axis=1))
    for begin in range(0, finite.size, chunk):
        rows = finite[begin:begin + chunk]
        block = points[rows]
        best = np.full(rows.size, math.inf)
        for path in polylines:
            count = min(candidates, path.shape[0])
            # |x - v|^2 up to the constant |x|^2, enough to rank the vertices.
            ranking = np.einsum('ij,ij->i', path, path)[np.newaxis] - 2.0 * block @ path.T
            nearest = np.argpartition(ranking, count - 1, axis=1)[:, :count]
            for vertex in nearest.T:
                before = np.maximum(vertex - 1, 0)
                after = np.minimum(vertex + 1, path.shape[0] - 1)
                best = np.minimum(best, np.minimum(
                    _segment_distance(block, path[before], path[vertex]),
                    _segment_distance(block, path[vertex], path[after])))
        distances[rows] = best
    return distances


def _segment_distance(points, start, end):
    """Row-wise distance from points to segments start -> end, all (N, 3)."""
    chord = end - start
    length_sq = np.einsum('ij,ij->i', chord, chord)
    along = np.einsum('ij,ij->i', points - start, chord)
    fraction = np.clip(along / np.where(length_sq > 0.0, length_sq, 1.0), 0.0, 1.0)
    return np.linalg.norm(points - start - fraction[:, np.newaxis] * chord, axis=1)


def visit_times(times, positions, targets, tolerance):
    """
    When a TCP track first comes within ``tolerance`` of each target, in the given order.

    Target j is searched from the sample that reached target j - 1 on, so the result shows
    whether the targets were visited in order.

    Parameters
    ----------
    times : array_like, shape (N,)
        Sample times [s].
    positions : array_like, shape (N, 3)
        TCP positions [m].
    targets : array_like, shape (T, 3)
        Points to visit, in order [m].
    tolerance : float
        Largest distance that counts as a visit [m], > 0.

    Returns
    -------
    numpy.ndarray, shape (T,)
        Visit times [s]; NaN from the first target never reached on.

    """
    tolerance = require_range('tolerance', tolerance, 0.0, low_open=True, unit='m')
    times = np.asarray(times, dtype=float)
    positions = np.asarray(positions, dtype=float)
    result = np.full(len(targets), math.nan)
    start = 0
    for index, target in enumerate(np.asarray(targets, dtype=float)):
        close = np.linalg.norm(positions[start:] - target, axis=1) <= tolerance
        if not close.any():
            break
        start += int(np.argmax(close))
        result[index] = times[start]
    return result
