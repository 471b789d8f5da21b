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
``ellipath demo``: a pick-and-place cell in one command, checked end to end over ROS 2.

:func:`run_demo` starts ``ellipath_node`` in this process (an executor thread of its own, an
rclpy context of its own) and a separate client node that plays the cell. The client sends a
conveyor-like stream of pick/place pairs, one pair at a time, with one deliberately
unreachable pair among them; for each pair it waits for the trajectory or the diagnostics
status, checks what arrived and prints one table row as soon as the cycle completes, then a
summary.

Each trajectory is checked with ``validate_jtc`` (joint names as configured, strictly
increasing times, at rest at the end) and for what the cell needs beyond it: it starts at
rest where the robot is (the node's ``home_position``, then the end of the previous
trajectory), passes through the pick, ends at the place, and the controller's quintic
interpolation, sampled every 0.5 ms, keeps the joints within their position, velocity and
acceleration limits and the TCP within the useful workspace of the default robot (radius
0.4 m, z in [-1.0, -0.55] m).

DDS stays on this host: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is set to ``LOCALHOST`` unless the
environment already sets it to a non-empty value, which is respected (this changes
``os.environ`` of the calling process). Both nodes run in the namespace
``/ellipath_demo_<pid>`` on the domain ``--domain-id`` (default: ``ROS_DOMAIN_ID`` if set,
else 77), so they talk to no other ``ellipath_node`` or demo; only ``/diagnostics`` is
shared. A parameters file must therefore use the keys ``/**`` or ``/**/ellipath_node``.

Exit status: 0 when every good pair was planned into a trajectory that passed every check and
the bad pair was rejected (ERROR status, no trajectory); 1 when a check failed; 2 when the
parameters or options are invalid; 3 on a timeout; 130 on Ctrl-C.
"""

import argparse
from dataclasses import dataclass
from dataclasses import replace
import math
import os
from pathlib import Path
import sys
import threading
import time

from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.joint_trajectory import REST_TOLERANCE
from ellipath_ros.core.joint_trajectory import validate_jtc
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.timing import PROFILES
import numpy as np

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_INVALID = 2
EXIT_TIMEOUT = 3
EXIT_INTERRUPTED = 130

DEFAULT_CYCLES = 12
DEFAULT_DOMAIN_ID = 77
DEFAULT_TIMEOUT = 10.0  # s
# Domain ids whose DDS ports exist on Linux (ROS 2 documentation: 0 to 232).
MAX_DOMAIN_ID = 232
# Namespace of both nodes, followed by the process id: two demos on one domain stay apart.
NAMESPACE = 'ellipath_demo'
CLIENT_NAME = 'ellipath_demo_cell'
SPIN_STEP = 0.01  # s, longest single wait of the client's executor
# After a rejection or the last cycle: how long a stray trajectory has to show up.
SETTLE = 0.2  # s

# The cell, in the base frame [m]. A conveyor runs along y at x = -0.15; the picks advance
# along it and wrap around. The boxes, two columns of three, stand about 0.3 m away; the far
# column is 30 mm deeper.
CONVEYOR_X = -0.15
CONVEYOR_Z = -0.85
CONVEYOR_Y = (-0.20, 0.20)
CONVEYOR_STEP = 0.035
BOXES = tuple((x, y, z) for x, z in ((0.14, -0.80), (0.18, -0.83)) for y in (-0.08, 0.0, 0.08))
# The deliberately bad place: 0.9 m off the axis, far outside the reach of the robot.
BAD_PLACE = (0.90, 0.0, -0.80)
BAD_KIND = 'unreachable'

# The useful workspace of the default robot (DeltaGeometry): the TCP must stay in it.
WORKSPACE_RADIUS = 0.40  # m
WORKSPACE_Z = (-1.0, -0.55)  # m
# JTC's interpolation is checked at least this often, and at least this many times per knot
# segment, knots included.
CHECK_PERIOD = 0.0005  # s
MIN_SAMPLES_PER_SEGMENT = 16
# Start and end of a trajectory: this close to where the robot is and to the place [m].
POSITION_TOLERANCE = 1e-6
# Relative slack on the joint limits, for rounding only.
LIMIT_SLACK = 1e-6
# Keys of the node's OK status (the planner's CyclePlan.metrics).
PHI_KEY = 'transfer.phi_deg'
APEX_KEY = 'transfer.apex_height'
PLAN_TIME_KEY = 'plan_time'
_MM = 1e3
_MS = 1e3


def add_arguments(parser):
    """Add the options of ``ellipath demo`` to an argparse parser."""
    parser.add_argument(
        '--cycles', type=_positive_int, default=DEFAULT_CYCLES,
        help='pick/place pairs to send, one of them deliberately unreachable '
             '(default: %(default)s)')
    parser.add_argument(
        '--profile', choices=PROFILES, default=None,
        help='motion profile, overriding the parameters file (time_optimal is the default, '
             "curvature the paper's)")
    parser.add_argument(
        '--params-file', type=Path, default=None,
        help='parameters of ellipath_node (YAML, under /** or /**/ellipath_node: the node runs '
             'in the namespace /ellipath_demo_<pid>); default: config/ellipath.yaml of the '
             'source tree or of the installed package, else the node defaults')
    parser.add_argument(
        '--timeout', type=_positive_float, default=DEFAULT_TIMEOUT,
        help='seconds to wait for discovery and for the answer to each pair; exit status 3 '
             'when exceeded (default: %(default)s)')
    parser.add_argument(
        '--domain-id', type=_domain_id, default=None,
        help=f'ROS domain id (default: ROS_DOMAIN_ID if set, else {DEFAULT_DOMAIN_ID}); DDS '
             'stays on this host unless ROS_AUTOMATIC_DISCOVERY_RANGE says otherwise')


def _positive_int(text):
    """Parse an integer >= 1 (argparse type)."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'expected an integer >= 1, got {text}')
    return value


def _positive_float(text):
    """Parse a finite number > 0 (argparse type)."""
    value = float(text)
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f'expected a number > 0, got {text}')
    return value


def _domain_id(text):
    """Parse a ROS domain id (argparse type)."""
    value = int(text)
    if not 0 <= value <= MAX_DOMAIN_ID:
        raise argparse.ArgumentTypeError(
            f'expected a domain id in [0, {MAX_DOMAIN_ID}], got {text}')
    return value


def cell_pairs(cycles):
    """
    Return the demo's pick/place pairs and the index of the deliberately bad one.

    Parameters
    ----------
    cycles : int
        Number of pairs, >= 1.

    Returns
    -------
    tuple
        (list of (pick, place) float arrays (3,) [m], index of the bad pair). The bad pair is
        in the middle, so good pairs come before and after it.

    """
    bad = cycles // 2
    span = CONVEYOR_Y[1] - CONVEYOR_Y[0]
    pairs = []
    for index in range(cycles):
        pick = (CONVEYOR_X, CONVEYOR_Y[0] + (index * CONVEYOR_STEP) % span, CONVEYOR_Z)
        place = BAD_PLACE if index == bad else BOXES[index % len(BOXES)]
        pairs.append((np.array(pick, dtype=float), np.array(place, dtype=float)))
    return pairs, bad


# Clock difference allowed between the node's stamps and this client's receipt times [s].
STAMP_SLACK = 0.05


def default_params_file():
    """
    Return config/ellipath.yaml of the source tree or the installed share dir, or None.

    Looked up in the source tree, then through the ament index (a colcon install, or
    AMENT_PREFIX_PATH), then under this Python's prefix (where ``pip install .`` puts it).
    """
    relative = Path('config') / 'ellipath.yaml'
    candidates = [Path(__file__).resolve().parents[1] / relative]
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory('ellipath_ros')) / relative)
    except (ImportError, LookupError, OSError):
        # No ament index module, package not in the index, or AMENT_PREFIX_PATH unset.
        pass
    candidates.append(Path(sys.prefix) / 'share' / 'ellipath_ros' / relative)
    return next((path for path in candidates if path.is_file()), None)


@dataclass(frozen=True)
class TrajectoryCheck:
    """
    What the checks of one trajectory found.

    Attributes
    ----------
    problems : tuple of str
        One message per broken rule; empty when the trajectory is valid.
    end_position : numpy.ndarray or None
        TCP position at the last point [m], (3,), where the robot stops; None when unknown.
    duration : float
        Time of the last point [s] (NaN when unknown).
    peak_tcp_speed, peak_tcp_accel : float
        Largest TCP speed [m/s] and acceleration norm [m/s^2] of JTC's interpolation.
    peak_joint_velocity, peak_joint_accel : float
        Largest |q_dot| [rad/s] and |q_ddot| [rad/s^2] of JTC's interpolation.

    """

    problems: tuple
    end_position: object = None
    duration: float = math.nan
    peak_tcp_speed: float = math.nan
    peak_tcp_accel: float = math.nan
    peak_joint_velocity: float = math.nan
    peak_joint_accel: float = math.nan


def check_trajectory(trajectory, start, pick, place, config):
    """
    Check one trajectory as joint_trajectory_controller would run it.

    Parameters
    ----------
    trajectory : ellipath_ros.core.joint_trajectory.JointTrajectoryData
        The trajectory as received.
    start : array_like, shape (3,)
        Where the robot is when the trajectory starts [m].
    pick, place : array_like, shape (3,)
        The pair the trajectory serves [m].
    config : ellipath_ros.core.planner.PlannerConfig
        The node's configuration: joint names, geometry and joint position limits, joint
        velocity and acceleration limits, knot tolerance.

    Returns
    -------
    TrajectoryCheck
        The problems found (none for a valid trajectory) and the measured peaks.

    """
    try:
        validate_jtc(trajectory, expect_names=config.joint_names)
    except EllipathError as error:
        # The arrays may be unusable: nothing else can be checked.
        return TrajectoryCheck((f'validate_jtc: {error}',))
    times = trajectory.time_from_start
    if times.size < 2:
        return TrajectoryCheck(('a single point: the robot does not move',))
    geometry, limits, names = config.geometry, config.joint_limits, config.joint_names
    problems = []

    knots = forward_kinematics(trajectory.positions, geometry, strict=False)
    if not np.linalg.norm(knots[0] - start) <= POSITION_TOLERANCE:
        problems.append(f'starts at {_mm(knots[0])} mm, not where the robot is '
                        f'({_mm(start)} mm)')
    if not (np.abs(trajectory.velocities[0]).max() <= REST_TOLERANCE
            and np.abs(trajectory.accelerations[0]).max() <= REST_TOLERANCE):
        problems.append('does not start at rest')
    if not np.linalg.norm(knots[-1] - place) <= POSITION_TOLERANCE:
        problems.append(f'ends at {_mm(knots[-1])} mm, not at the place ({_mm(place)} mm)')

    grid = _sample_times(times)
    q, qdot, qddot = quintic_interpolate(trajectory, grid)
    tcp = forward_kinematics(q, geometry, strict=False)
    miss = np.nanmin(np.linalg.norm(tcp - pick, axis=1), initial=math.inf)
    if not miss <= config.knot_tolerance + POSITION_TOLERANCE:
        problems.append(f'passes {miss * _MM:.3f} mm from the pick (tolerance '
                        f'{config.knot_tolerance * _MM:g} mm)')
    problems.extend(_limit_problems(grid, q, qdot, qddot, geometry, limits, names))
    problems.extend(_workspace_problems(grid, tcp))

    velocity = np.gradient(tcp, grid, axis=0)
    acceleration = np.gradient(velocity, grid, axis=0)
    return TrajectoryCheck(
        tuple(problems), end_position=knots[-1], duration=float(times[-1]),
        peak_tcp_speed=_peak(np.linalg.norm(velocity, axis=1)),
        peak_tcp_accel=_peak(np.linalg.norm(acceleration, axis=1)),
        peak_joint_velocity=_peak(np.abs(qdot)), peak_joint_accel=_peak(np.abs(qddot)))


def _sample_times(times):
    """Return sample times covering every knot segment evenly, knots included."""
    per_segment = max(MIN_SAMPLES_PER_SEGMENT,
                      int(math.ceil(np.diff(times).max() / CHECK_PERIOD)))
    fractions = np.arange(per_segment) / per_segment
    grid = (times[:-1, np.newaxis] + np.diff(times)[:, np.newaxis] * fractions).ravel()
    return np.append(grid, times[-1])


def _limit_problems(grid, q, qdot, qddot, geometry, limits, names):
    """Return a message for each joint quantity that leaves its limits, at its worst sample."""
    problems = []
    checks = (
        ('position', np.maximum(geometry.joint_min - q, q - geometry.joint_max), q,
         f'[{geometry.joint_min:g}, {geometry.joint_max:g}] rad',
         LIMIT_SLACK * (geometry.joint_max - geometry.joint_min)),
        ('velocity', np.abs(qdot) - limits.max_velocity, qdot,
         f'|q_dot| <= {limits.max_velocity:g} rad/s', LIMIT_SLACK * limits.max_velocity),
        ('acceleration', np.abs(qddot) - limits.max_acceleration, qddot,
         f'|q_ddot| <= {limits.max_acceleration:g} rad/s^2',
         LIMIT_SLACK * limits.max_acceleration))
    for quantity, excess, values, bound, slack in checks:
        sample, joint = np.unravel_index(int(np.argmax(excess)), excess.shape)
        if excess[sample, joint] > slack:
            problems.append(f'{names[joint]} {quantity} {values[sample, joint]:.6g} breaks '
                            f'{bound} at t={grid[sample]:.4f} s')
    return problems


def _workspace_problems(grid, tcp):
    """Return a message if the interpolated TCP leaves the workspace (or cannot be built)."""
    broken = ~np.isfinite(tcp).all(axis=1)
    if broken.any():
        return [f'the arms cannot be assembled at t={grid[int(np.argmax(broken))]:.4f} s']
    radius = np.hypot(tcp[:, 0], tcp[:, 1])
    outside = ((radius > WORKSPACE_RADIUS) | (tcp[:, 2] < WORKSPACE_Z[0])
               | (tcp[:, 2] > WORKSPACE_Z[1]))
    if not outside.any():
        return []
    sample = int(np.argmax(outside))
    return [f'TCP {_mm(tcp[sample])} mm at t={grid[sample]:.4f} s leaves the workspace '
            f'(radius <= {WORKSPACE_RADIUS * _MM:g} mm, z in [{WORKSPACE_Z[0] * _MM:g}, '
            f'{WORKSPACE_Z[1] * _MM:g}] mm)']


def _peak(values):
    """Return the largest finite entry of ``values`` (NaN if there is none)."""
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else math.nan


def _mm(point):
    """Format a point [m] as whole millimetres, '(x, y, z)'."""
    return '(' + ','.join(f'{value * _MM:4.0f}' for value in np.asarray(point)) + ')'


@dataclass
class CycleResult:
    """
    One pick/place pair: what was sent, what came back, and the verdict.

    Attributes
    ----------
    index : int
        0-based cycle number.
    pick, place : numpy.ndarray
        The pair [m].
    bad : bool
        True for the deliberately bad pair.
    verdict : str
        ``'ok'``, ``'rejected_expected'``, ``'rejected_unexpected'``, ``'invalid'`` (a
        trajectory failed a check), ``'not_rejected'`` (the bad pair was planned) or
        ``'timeout'``.
    reason : str
        The rejection reason, or the problems found.
    values : dict
        The key/values of the node's final status for this pair.
    check : TrajectoryCheck or None
        The check of the trajectory, if one arrived.
    round_trip : float
        Place sent to answer received [s] (NaN on a timeout).
    invalid_published : int
        Trajectories published for this pair that should not have been (failed checks,
        published with a rejection, or more than one).

    """

    index: int
    pick: np.ndarray
    place: np.ndarray
    bad: bool
    verdict: str = 'timeout'
    reason: str = ''
    values: dict = None
    check: TrajectoryCheck = None
    round_trip: float = math.nan
    invalid_published: int = 0

    def number(self, key):
        """Return the node's value ``key`` as a float (NaN when missing or not a number)."""
        try:
            return float((self.values or {})[key])
        except (KeyError, ValueError):
            return math.nan


def evaluate_cycle(result, trajectories, statuses, start, config):
    """
    Judge one pair from the messages that answered it; fill in ``result``.

    Parameters
    ----------
    result : CycleResult
        The pair; its verdict, reason, values, check and invalid_published are set here.
    trajectories : list of (JointTrajectoryData or None, tuple of str)
        The trajectories received for the pair, each with the problems of its message
        (header, malformed points; the data is None when it cannot be read).
    statuses : list of (str, str, dict)
        The node's statuses about the pair in arrival order: level ('OK', 'WARN', 'ERROR'),
        message and key/values.
    start : numpy.ndarray
        Where the robot is [m].
    config : ellipath_ros.core.planner.PlannerConfig
        The node's configuration.

    """
    errors = [(message, values) for level, message, values in statuses if level == 'ERROR']
    result.values = next((values for level, _, values in reversed(statuses) if level != 'WARN'),
                         {})
    checks = []
    for data, message_problems in trajectories:
        check = (TrajectoryCheck(()) if data is None else
                 check_trajectory(data, start, result.pick, result.place, config))
        checks.append(replace(check, problems=message_problems + check.problems))
    result.check = checks[0] if checks else None
    if errors:
        message, values = errors[0]
        result.reason = message
        if checks:
            result.verdict, result.invalid_published = 'invalid', len(checks)
            result.reason = f'a trajectory was published despite the rejection: {message}'
        elif result.bad and values.get('kind') == BAD_KIND:
            result.verdict = 'rejected_expected'
        else:
            result.verdict = 'rejected_unexpected'
        return
    problems = list(checks[0].problems) if checks else ['no trajectory']
    if len(checks) > 1:
        problems.insert(0, f'{len(checks)} trajectories for one pair')
    result.invalid_published = bool(checks and checks[0].problems) + max(len(checks) - 1, 0)
    if problems:
        result.verdict, result.reason = 'invalid', '; '.join(problems)
    elif result.bad:
        result.verdict = 'not_rejected'
        result.reason = f'expected a rejection ({BAD_KIND}) of the place {_mm(result.place)} mm'
    else:
        result.verdict = 'ok'


STATUS_LABELS = {
    'ok': 'OK',
    'rejected_expected': 'REJECTED (expected)',
    'rejected_unexpected': 'REJECTED (unexpected)',
    'invalid': 'INVALID',
    'not_rejected': 'PLANNED (bad pair)',
    'timeout': 'TIMEOUT',
}

# Table columns: title, unit, width, format, value of a CycleResult (NaN prints as '-').
_COLUMNS = (
    ('phi', '[deg]', 5, '.1f', lambda result: result.number(PHI_KEY)),
    ('apex', '[mm]', 5, '.1f', lambda result: result.number(APEX_KEY) * _MM),
    ('duration', '[ms]', 8, '.1f', lambda result: _checked(result, 'duration') * _MS),
    ('v_tcp', '[m/s]', 6, '.2f', lambda result: _checked(result, 'peak_tcp_speed')),
    ('a_tcp', '[m/s2]', 6, '.1f', lambda result: _checked(result, 'peak_tcp_accel')),
    ('qd', '[rad/s]', 7, '.2f', lambda result: _checked(result, 'peak_joint_velocity')),
    ('qdd', '[rad/s2]', 8, '.1f', lambda result: _checked(result, 'peak_joint_accel')),
    ('plan', '[ms]', 6, '.1f', lambda result: result.number(PLAN_TIME_KEY) * _MS),
)
_PAIR_WIDTH = 36


def _checked(result, name):
    """Return a measured value of the cycle's trajectory, NaN without one."""
    return getattr(result.check, name) if result.check is not None else math.nan


def table_header():
    """Return the two header lines of the cycle table."""
    titles = [f'{"#":>4}  {"pick -> place":<{_PAIR_WIDTH}}']
    units = [f'{"":>4}  {"[mm]":<{_PAIR_WIDTH}}']
    for title, unit, width, _, _ in _COLUMNS:
        titles.append(f'{title:>{width}}')
        units.append(f'{unit:>{width}}')
    return ' '.join(titles) + '  status\n' + ' '.join(units) + '\n'


def table_row(result):
    """Return the table line of one cycle."""
    cells = [f'{result.index + 1:>4}  '
             f'{_mm(result.pick) + " -> " + _mm(result.place):<{_PAIR_WIDTH}}']
    for _, _, width, spec, value_of in _COLUMNS:
        value = value_of(result)
        cells.append(f'{value:>{width}{spec}}' if math.isfinite(value) else f'{"-":>{width}}')
    status = STATUS_LABELS[result.verdict]
    if result.reason:
        status += ': ' + ' '.join(result.reason.split())
    return ' '.join(cells) + '  ' + status + '\n'


def summary(results, cycles, wall_time, config):
    """Return the summary lines of a run under the node's configuration ``config``."""
    verdicts = [result.verdict for result in results]
    planned = [result for result in results if result.check is not None]
    latencies = [result.number(PLAN_TIME_KEY) for result in planned]
    latencies = [value for value in latencies if math.isfinite(value)]
    durations = [result.check.duration for result in planned
                 if math.isfinite(result.check.duration)]
    round_trips = [result.round_trip for result in planned]
    lines = [
        f'cycles: {len(results)} of {cycles} run, {len(planned)} planned, '
        f'{verdicts.count("ok")} valid, {verdicts.count("rejected_expected")} rejected as '
        f'expected, {verdicts.count("rejected_unexpected")} rejected unexpectedly, '
        f'{sum(result.invalid_published for result in results)} invalid published',
    ]
    if latencies:
        lines.append(f'plan latency: mean {np.mean(latencies) * _MS:.1f} ms, max '
                     f'{np.max(latencies) * _MS:.1f} ms; place sent to trajectory received: '
                     f'mean {np.mean(round_trips) * _MS:.1f} ms')
    if planned:
        limits, joints = config.limits, config.joint_limits
        lines.append(
            'peaks of the interpolated trajectories: TCP '
            f'{_peak_of(planned, "peak_tcp_speed"):.2f} m/s (limit {limits.max_speed:g}), '
            f'{_peak_of(planned, "peak_tcp_accel"):.1f} m/s2 (limit {limits.max_accel:g}); '
            f'joints {_peak_of(planned, "peak_joint_velocity"):.2f} rad/s (limit '
            f'{joints.max_velocity:g}), {_peak_of(planned, "peak_joint_accel"):.1f} rad/s2 '
            f'(limit {joints.max_acceleration:g})')
    if durations:
        mean = float(np.mean(durations))
        lines.append(f'cycle duration: mean {mean * _MS:.1f} ms -> throughput '
                     f'{60.0 / mean:.1f} picks/min (trajectories back to back)')
    lines.append(f'wall time: {wall_time:.2f} s (discovery and cycles)')
    return ''.join(line + '\n' for line in lines)


def _peak_of(results, name):
    """Return the largest measured ``name`` over the trajectories of ``results``."""
    values = [getattr(result.check, name) for result in results]
    return max((value for value in values if math.isfinite(value)), default=math.nan)


def run_demo(args):
    """
    Run the demo; return the exit status.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_arguments`.

    Returns
    -------
    int
        0 when every check passed, 1 when one failed, 2 for invalid parameters, 3 on a
        timeout, 130 on Ctrl-C.

    """
    try:
        return _run(args)
    except KeyboardInterrupt:
        sys.stderr.write('\nellipath demo: interrupted\n')
        return EXIT_INTERRUPTED


def _settings_error(message):
    """Report an invalid option or parameter; return the exit status."""
    sys.stderr.write(f'ellipath demo: {message}\n')
    return EXIT_INVALID


def _run(args):
    """Set up, run every cycle, tear down; return the exit status."""
    params_file = args.params_file if args.params_file is not None else default_params_file()
    if params_file is not None and not params_file.is_file():
        return _settings_error(f'--params-file: expected a YAML file, got {params_file}')
    domain_id = args.domain_id
    if domain_id is None:
        try:
            domain_id = _domain_id(os.environ.get('ROS_DOMAIN_ID', '') or DEFAULT_DOMAIN_ID)
        except (ValueError, argparse.ArgumentTypeError) as error:
            return _settings_error(f'ROS_DOMAIN_ID: {error}')
    # Keep DDS discovery on this host unless the user chose a range (rmw reads it at init;
    # empty means the default, SUBNET).
    if not os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE'):
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

    # ROS is imported here, not at the top, so that the rest of the CLI runs without ROS.
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    # No rclpy signal handlers: Ctrl-C raises KeyboardInterrupt here, handled by run_demo.
    rclpy.init(args=[], context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        return _run_in_context(args, context, params_file, domain_id)
    finally:
        rclpy.try_shutdown(context=context)


def _run_in_context(args, context, params_file, domain_id):
    """Start the node and the cell in ``context``, run the cycles; return the exit status."""
    from ellipath_ros.node import EllipathNode
    from ellipath_ros.parameters import build_settings
    from ellipath_ros.parameters import PARAMETER_NAMES
    from rclpy.exceptions import ParameterException
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    cli_args = ['--ros-args', '--params-file', str(params_file)] if params_file else None
    overrides = [Parameter('profile', value=args.profile)] if args.profile else []
    try:
        node = EllipathNode(context=context, namespace=f'{NAMESPACE}_{os.getpid()}',
                            cli_args=cli_args, parameter_overrides=overrides)
    except (EllipathError, ParameterException, RuntimeError) as error:
        # rcl reports a params file it cannot parse as a RuntimeError (RCLError).
        return _settings_error(f'cannot start the node: {" ".join(str(error).split())}')
    settings = build_settings({name: node.get_parameter(name).value
                               for name in PARAMETER_NAMES})
    # One thread: once spin() has returned no callback is running, so the node can be
    # destroyed safely (MultiThreadedExecutor.shutdown does not wait for its workers).
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, name=node.get_name(), daemon=True)
    spinner.start()
    cell = None
    try:
        cell = _Cell(context, node, settings)
        header = (f'ellipath demo: {args.cycles} pick/place pairs to {node.get_namespace()}/'
                  f'{node.get_name()} on ROS domain {domain_id} (discovery range '
                  f'{os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"]}); profile '
                  f'{settings.planner.profile}; parameters {params_file or "node defaults"}')
        return _run_cycles(args, cell, settings, header)
    finally:
        if cell is not None:
            cell.close()
        executor.shutdown(timeout_sec=args.timeout)
        spinner.join(timeout=args.timeout)
        node.destroy_node()


def _run_cycles(args, cell, settings, header):
    """Send every pair, print the table and the summary; return the exit status."""
    out = sys.stdout
    pairs, bad = cell_pairs(args.cycles)
    out.write(f'{header}\npair {bad + 1} is deliberately bad: place {_mm(BAD_PLACE)} mm is '
              'out of reach\n')
    out.flush()
    started = time.monotonic()
    failure = cell.wait_for_node(args.timeout)
    if failure is not None:
        status, message = failure
        sys.stderr.write(f'ellipath demo: {message}\n')
        return status
    out.write('\n' + table_header())
    out.flush()
    results = []
    try:
        _send_pairs(pairs, bad, args.timeout, cell, settings, results, out)
    except KeyboardInterrupt:
        # Ctrl-C: stop sending, and still report the cycles that completed.
        elapsed = time.monotonic() - started
        out.write('\n' + summary(results, args.cycles, elapsed, settings.planner))
        out.write(f'result: INTERRUPTED after {len(results)} of {args.cycles} cycles\n')
        out.flush()
        return EXIT_INTERRUPTED
    stray = cell.stray_trajectories(SETTLE)
    verdicts = [result.verdict for result in results]
    passed = (not stray and all(verdict in ('ok', 'rejected_expected') for verdict in verdicts)
              and not any(result.invalid_published for result in results))
    elapsed = time.monotonic() - started
    out.write('\n' + summary(results, args.cycles, elapsed, settings.planner))
    if stray:
        out.write(f'invalid: {stray} trajectories arrived after the last cycle\n')
    out.write(f'result: {"PASS" if passed else "FAIL"}\n')
    out.flush()
    if 'timeout' in verdicts:
        return EXIT_TIMEOUT
    return EXIT_OK if passed else EXIT_FAILED


def _send_pairs(pairs, bad, timeout, cell, settings, results, out):
    """Run the cycles one by one, appending to ``results`` and printing each row at once."""
    start = np.asarray(settings.home_position, dtype=float)  # no joint_states: the node's too
    for index, (pick, place) in enumerate(pairs):
        result = CycleResult(index, pick, place, index == bad)
        answer = cell.exchange(pick, place, timeout)
        if answer is None:
            result.reason = f'no answer within {timeout:g} s'
        else:
            trajectories, statuses, result.round_trip = answer
            evaluate_cycle(result, trajectories, statuses, start, settings.planner)
            if result.check is not None and result.check.end_position is not None:
                start = result.check.end_position  # the robot stops where it ended
        results.append(result)
        out.write(table_row(result))
        out.flush()
        if answer is None:
            return


_LEVELS = {b'\x00': 'OK', b'\x01': 'WARN', b'\x02': 'ERROR', b'\x03': 'STALE'}


class _Cell:
    """
    The client side of the demo: a node of its own that sends pairs and collects answers.

    Its subscriptions are served by its own single-threaded executor, spun only by the caller,
    so the lists of received messages need no lock.

    Parameters
    ----------
    context : rclpy.context.Context
        The initialised context shared with the planning node.
    planner : ellipath_ros.node.EllipathNode
        The planning node (its names filter the diagnostics; its pending pick count tells when
        a pick has been taken).
    settings : ellipath_ros.parameters.NodeSettings
        The node's settings (frame and header stamp convention).

    """

    def __init__(self, context, planner, settings):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from trajectory_msgs.msg import JointTrajectory

        self._planner = planner
        self._settings = settings
        self._pose_type = PoseStamped
        self._status_name = f'{planner.get_name()}: plan'
        self.node = Node(CLIENT_NAME, namespace=planner.get_namespace(), context=context)
        depth = settings.queue_depth
        self._pick_publisher = self.node.create_publisher(PoseStamped, 'pick_pose', depth)
        self._place_publisher = self.node.create_publisher(PoseStamped, 'place_pose', depth)
        self._trajectories = []  # (message, wall-clock time of receipt)
        self._busy_until = None  # wall-clock time the last received trajectory ends
        self._statuses = []  # (level, message, values) of the planner's statuses
        self._consumed = 0  # trajectories already handed out by exchange()
        self._trajectory_subscription = self.node.create_subscription(
            JointTrajectory, 'joint_trajectory',
            lambda message: self._trajectories.append((message, time.time())), depth)
        # /diagnostics is shared by every node of the domain: keep a longer queue.
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                      100)
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self.node)

    def close(self):
        """Stop the executor and destroy the node."""
        self._executor.shutdown()
        self.node.destroy_node()

    def _on_diagnostics(self, message):
        """Keep the planner's statuses as (level, message, values)."""
        hardware_id = self._planner.get_fully_qualified_name()
        for status in message.status:
            if status.name == self._status_name and status.hardware_id == hardware_id:
                self._statuses.append((
                    _LEVELS.get(bytes(status.level), 'STALE'), status.message,
                    {item.key: item.value for item in status.values}))

    def _spin_until(self, condition, timeout):
        """Spin until ``condition()`` holds; return whether it did within ``timeout``."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self._executor.spin_once(timeout_sec=SPIN_STEP)
        return True

    def wait_for_node(self, timeout):
        """
        Wait until the planner and the cell have discovered each other.

        Returns None when they have, else (exit status, message).
        """
        name, namespace = self._planner.get_name(), self._planner.get_namespace()

        def matched():
            return (self._pick_publisher.get_subscription_count() > 0
                    and self._place_publisher.get_subscription_count() > 0
                    and self._trajectory_subscription.get_publisher_count() > 0
                    and any(info.node_name == name and info.node_namespace == namespace
                            for info in self.node.get_publishers_info_by_topic('/diagnostics')))

        if not self._spin_until(matched, timeout):
            return EXIT_TIMEOUT, (f'{name} and the cell did not discover each other within '
                                  f'{timeout:g} s')
        return None

    def _pose(self, position, stamp):
        """Return a PoseStamped at ``position`` in the node's frame, level orientation."""
        message = self._pose_type()
        message.header.frame_id = self._settings.frame_id
        message.header.stamp = stamp
        point = message.pose.position
        point.x, point.y, point.z = (float(value) for value in position)
        message.pose.orientation.w = 1.0
        return message

    def exchange(self, pick, place, timeout):
        """
        Send one pair and collect the planner's answer.

        Returns
        -------
        tuple or None
            (trajectories as :func:`evaluate_cycle` takes them, statuses as (level, message,
            values), place sent to answer received [s]); None when the answer did not come
            within ``timeout`` seconds (at each of the two steps).

        """
        first_status = len(self._statuses)
        # One stamp for both poses: they pair in the 'stamp' pairing mode too.
        stamp = self.node.get_clock().now().to_msg()
        pending = self._planner.pending_pick_count
        self._pick_publisher.publish(self._pose(pick, stamp))

        # Pick and place travel on separate topics and could overtake each other: send the
        # place only once the node holds the pick or has said why it does not.
        def pick_taken():
            return (self._planner.pending_pick_count != pending
                    or any(values.get('topic') == 'pick_pose'
                           for _, _, values in self._statuses[first_status:]))

        if not self._spin_until(pick_taken, timeout):
            return None
        sent = time.perf_counter()
        self._place_publisher.publish(self._pose(place, stamp))

        def rejected():
            return any(level == 'ERROR' and values.get('topic') == 'place_pose'
                       for level, _, values in self._statuses[first_status:])

        def answered():
            planned = (any(level == 'OK' for level, _, _ in self._statuses[first_status:])
                       and len(self._trajectories) > self._consumed)
            return planned or rejected()

        if not self._spin_until(answered, timeout):
            return None
        round_trip = time.perf_counter() - sent
        if rejected():
            self._spin_until(lambda: False, SETTLE)  # no trajectory may follow a rejection
        trajectories = [self._read(message, received)
                        for message, received in self._trajectories[self._consumed:]]
        self._consumed = len(self._trajectories)
        return trajectories, self._statuses[first_status:], round_trip

    def _read(self, message, received):
        """Return (JointTrajectoryData or None, problems of the message) of a trajectory."""
        from ellipath_ros.conversions import joint_trajectory_data

        problems = []
        if message.header.frame_id != self._settings.frame_id:
            problems.append(f'header.frame_id {message.header.frame_id!r}, expected '
                            f'{self._settings.frame_id!r}')
        stamp = message.header.stamp.sec + 1e-9 * message.header.stamp.nanosec
        running = self._busy_until is not None and received < self._busy_until - STAMP_SLACK
        if running and abs(stamp - self._busy_until) > STAMP_SLACK:
            problems.append(f'header.stamp {stamp:.3f} s while the last trajectory runs until '
                            f'{self._busy_until:.3f} s: the robot would be cut short')
        elif not running and self._settings.header_stamp == 'zero' and stamp:
            problems.append('header.stamp is not zero (JTC would not start it on receipt)')
        if message.points:
            last = message.points[-1].time_from_start
            self._busy_until = ((stamp or received) + last.sec + 1e-9 * last.nanosec)
        if any(len(point.effort) for point in message.points):
            problems.append('effort entries (JTC rejects them without an effort interface)')
        try:
            return joint_trajectory_data(message), tuple(problems)
        except EllipathError as error:
            return None, tuple(problems + [f'malformed: {error}'])

    def stray_trajectories(self, settle):
        """Spin ``settle`` seconds; return how many trajectories came after the last pair."""
        self._spin_until(lambda: False, settle)
        return len(self._trajectories) - self._consumed
