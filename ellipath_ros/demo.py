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
``ellipath demo``: a pick-and-place cell in one command, judged on the executed motion.

:func:`run_demo` starts ``ellipath_node`` in this process (an executor thread of its own, an
rclpy context of its own) and a separate client node that plays the cell. The client sends a
conveyor-like stream of pick/place pairs with two deliberately bad pairs among them (a place
out of reach, and an object behind the conveyor's frame, whose path would cross it), and
records the node's answer to each pair and every trajectory with its ``header.stamp``
and the time it arrived. Pacing (``--pacing``):

* ``burst`` (default): the pairs go out as fast as the node takes them, far faster than the
  robot executes them, as when a camera sees several objects at once. Each place is sent once
  the node holds its pick (the two travel on separate topics) and has answered the pair
  before, so that answers can be told apart; the trajectories are not waited for.
* ``idle``: each pair is sent once the trajectory of the previous one has ended, so the robot
  is idle whenever a pair arrives.

Then :mod:`ellipath_ros.demo_report` replays the trajectories at their arrival times through
the emulation of Jazzy's joint_trajectory_controller and prints what the robot executes:
picks/min and the gaps between trajectories from the executed timeline, the largest deviation
of the executed TCP from the planned paths, whether every pick and place was visited in
order, the joint limits of the executed command, the executed TCP against the node's safe
workspace, and the rejections of the bad pairs.

The cell's safe workspace is the node's own (``workspace_radius``, ``workspace_z_min``,
``workspace_z_max`` from the parameters): the demo adds the conveyor's frame as
``keep_out_boxes`` (``CELL_KEEP_OUT_BOXES``, replacing any boxes of the parameters file; not
in the ``--belt`` scenario), and the report judges the executed TCP with that same
:class:`~ellipath_ros.core.workspace.SafeWorkspace` and describes it.

DDS stays on this host: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is set to ``LOCALHOST`` unless the
environment already sets it to a non-empty value, which is respected (this changes
``os.environ`` of the calling process). Both nodes run in the namespace
``/ellipath_demo_<pid>`` on the domain ``--domain-id`` (default: ``ROS_DOMAIN_ID`` if set,
else 77), so they talk to no other ``ellipath_node`` or demo; only ``/diagnostics`` is
shared. A parameters file must therefore use the keys ``/**`` or ``/**/ellipath_node``.

Exit status: 0 when every check passed (every good pair planned and executed as planned, the
bad pairs rejected as unreachable and as leaving the safe workspace); 1 when a check failed;
2 when the parameters or options are invalid; 3 on a timeout; 130 on Ctrl-C.
"""

import argparse
import math
import os
from pathlib import Path
import sys
import threading
import time

from ellipath_ros.belt_demo import add_belt_arguments
from ellipath_ros.belt_demo import belt_options_error
from ellipath_ros.belt_demo import belt_parameters
from ellipath_ros.belt_demo import failures
from ellipath_ros.belt_demo import format_belt_report
from ellipath_ros.belt_demo import run_belt_demo
from ellipath_ros.belt_demo import run_node_belt
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.motion import PROFILES
from ellipath_ros.demo_report import evaluate_run
from ellipath_ros.demo_report import format_report
from ellipath_ros.demo_report import mm_text
from ellipath_ros.demo_report import PairOutcome
from ellipath_ros.demo_report import ReceivedTrajectory
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
# After the predicted end of the last trajectory: how long a stray one has to show up.
SETTLE = 0.2  # s
PACINGS = ('burst', 'idle')
# The message of the node's status for a planned pair.
PLANNED_MESSAGE = 'planned'
# Idle pacing: the next pair goes this long after the previous trajectory's predicted end
# (one control period, and a little for the clocks of the two nodes).
IDLE_MARGIN = 0.01  # s

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
# The conveyor's frame: its far side rail, 10 mm above the belt, beyond the picks (which the
# robot reaches straight from above) and on the side away from the boxes, so no good pair's
# path comes near it. [xmin, ymin, zmin, xmax, ymax, zmax] [m], as keep_out_boxes.
CELL_KEEP_OUT_BOXES = (-0.26, -0.30, -1.0, -0.21, 0.30, -0.84)
# The second bad pair: an object that fell behind that rail. Reachable, inside the cylinder,
# but the path to it and from it crosses the rail: the node must reject it as 'workspace'.
BEHIND_FRAME_PICK = (-0.30, 0.0, -0.90)
UNREACHABLE = 'unreachable'
OUTSIDE_WORKSPACE = 'workspace'


def add_arguments(parser):
    """Add the options of ``ellipath demo`` to an argparse parser."""
    parser.add_argument(
        '--cycles', type=_positive_int, default=DEFAULT_CYCLES,
        help='pick/place pairs to send, two of them deliberately bad (one unreachable, one '
             "crossing the conveyor's frame; only the first with fewer than 3) "
             '(default: %(default)s)')
    parser.add_argument(
        '--pacing', choices=PACINGS, default='burst',
        help='burst: send the pairs as fast as the node takes them (faster than the robot '
             'executes them); idle: send each pair once the previous trajectory has ended '
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
        help='seconds to wait for discovery, for the answer to each pair and, while '
             'trajectories are due, for the next one; exit status 3 when exceeded (default: '
             '%(default)s)')
    parser.add_argument(
        '--domain-id', type=_domain_id, default=None,
        help=f'ROS domain id (default: ROS_DOMAIN_ID if set, else {DEFAULT_DOMAIN_ID}); DDS '
             'stays on this host unless ROS_AUTOMATIC_DISCOVERY_RANGE says otherwise')
    add_belt_arguments(parser)


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
    Return the demo's pick/place pairs and the rejections expected of the bad ones.

    Parameters
    ----------
    cycles : int
        Number of pairs, >= 1.

    Returns
    -------
    tuple
        (list of (pick, place) float arrays (3,) [m], dict of the bad pairs' indices to the
        kind of rejection expected). The unreachable place is in the middle, the pick behind
        the conveyor's frame half-way from there to the end (from 3 pairs on), so good pairs
        come before, between and after them.

    """
    unreachable = cycles // 2
    expected = {unreachable: UNREACHABLE}
    behind_frame = (unreachable + cycles) // 2
    if behind_frame != unreachable:
        expected[behind_frame] = OUTSIDE_WORKSPACE
    span = CONVEYOR_Y[1] - CONVEYOR_Y[0]
    pairs = []
    for index in range(cycles):
        pick = (CONVEYOR_X, CONVEYOR_Y[0] + (index * CONVEYOR_STEP) % span, CONVEYOR_Z)
        place = BOXES[index % len(BOXES)]
        if expected.get(index) == UNREACHABLE:
            place = BAD_PLACE
        elif expected.get(index) == OUTSIDE_WORKSPACE:
            pick = BEHIND_FRAME_PICK
        pairs.append((np.array(pick, dtype=float), np.array(place, dtype=float)))
    return pairs, expected


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
        return run_belt_demo(args) if args.belt and args.belt_core else _run(args)
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
    # The cell's scene: the node plans around the conveyor's frame, and the report judges and
    # draws the same workspace (the settings read back from the node below). The belt
    # scenario has a scene of its own.
    overrides = ([] if args.belt else
                 [Parameter('keep_out_boxes', value=list(CELL_KEEP_OUT_BOXES))])
    if args.profile:
        overrides.append(Parameter('profile', value=args.profile))
    if args.belt:
        overrides += [Parameter(name, value=value)
                      for name, value in belt_parameters(args.belt_speed, args.place_belt)]
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
        what = (f'{args.objects} belt objects' if args.belt
                else f'{args.cycles} pick/place pairs')
        header = (f'ellipath demo: {what} to {node.get_namespace()}/'
                  f'{node.get_name()} on ROS domain {domain_id} (discovery range '
                  f'{os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"]}); profile '
                  f'{settings.planner.profile}; parameters {params_file or "node defaults"}')
        if args.belt:
            return _run_belt(args, cell, header)
        return _run_cycles(args, cell, settings, header)
    finally:
        if cell is not None:
            cell.close()
        executor.shutdown(timeout_sec=args.timeout)
        spinner.join(timeout=args.timeout)
        node.destroy_node()


def _run_cycles(args, cell, settings, header):
    """Send every pair, collect the answers, print the report; return the exit status."""
    out = sys.stdout
    pairs, expected = cell_pairs(args.cycles)
    out.write(f'{header}\nsafe workspace of the node: {settings.planner.workspace.describe()}'
              '; keep_out_boxes[0] is the frame of the conveyor\n')
    for index, kind in sorted(expected.items()):
        pick, place = pairs[index]
        why = (f'place {mm_text(place)} mm is out of reach' if kind == UNREACHABLE else
               f"pick {mm_text(pick)} mm lies behind the conveyor's frame: the path crosses it")
        out.write(f'pair {index + 1} is deliberately bad ({kind}): {why}\n')
    out.flush()
    started = time.monotonic()
    failure = cell.wait_for_node(args.timeout)
    if failure is not None:
        status, message = failure
        sys.stderr.write(f'ellipath demo: {message}\n')
        return status
    outcomes = [PairOutcome(index, pick, place, expected.get(index))
                for index, (pick, place) in enumerate(pairs)]
    start_time = time.time()
    try:
        answered = _send_pairs(outcomes, args, cell)
        sending = time.time() - start_time
        how = ('burst: each pair as soon as the node had answered the one before' if
               args.pacing == 'burst' else 'idle: each pair once the previous trajectory had '
               'ended')
        out.write(f'sent {answered} of {len(outcomes)} pairs in {sending:.2f} s ({how}); '
                  'waiting for the trajectories\n')
        out.flush()
        complete = answered == len(outcomes) and cell.wait_for_trajectories(
            sum(outcome.level == 'OK' for outcome in outcomes), args.timeout, SETTLE)
    except KeyboardInterrupt:
        # Ctrl-C: stop, and still say how far the run got.
        sent = sum(outcome.level is not None for outcome in outcomes)
        out.write(f'result: INTERRUPTED after {sent} of {len(outcomes)} pairs answered\n')
        out.flush()
        return EXIT_INTERRUPTED
    report = evaluate_run(outcomes, cell.received(), settings.home_position, settings.planner,
                          start_time, timed_out=not complete)
    out.write('\n' + format_report(report, settings.planner))
    out.write(f'wall time: {time.monotonic() - started:.2f} s (discovery, sending, '
              'execution)\n')
    out.flush()
    if report.passed:
        return EXIT_OK
    return EXIT_TIMEOUT if report.timed_out else EXIT_FAILED


def _run_belt(args, cell, header):
    """Run the belt scenario through the node, print its report; return the exit status."""
    error = belt_options_error(args)
    if error is not None:
        return _settings_error(f'--belt: {error}')
    sys.stdout.write(f'{header}\n')
    sys.stdout.flush()
    failure = cell.wait_for_node(args.timeout)
    if failure is not None:
        sys.stderr.write(f'ellipath demo: {failure[1]}\n')
        return failure[0]
    result, timed_out = run_node_belt(args, cell, args.timeout)
    if timed_out:
        sys.stderr.write('ellipath demo --belt: timed out waiting for the node\n')
        return EXIT_TIMEOUT
    sys.stdout.write(format_belt_report(result))
    return EXIT_FAILED if failures(result) else EXIT_OK


def _send_pairs(outcomes, args, cell):
    """Send the pairs with the chosen pacing, filling in the answers; return how many."""
    for count, outcome in enumerate(outcomes):
        if not cell.send_pair(outcome, args.timeout):
            return count
        if args.pacing == 'idle' and outcome.level == 'OK':
            if not cell.wait_until_idle(args.timeout, IDLE_MARGIN):
                return count + 1
    return len(outcomes)


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
        The node's settings (frame of the poses, queue depth).

    """

    def __init__(self, context, planner, settings):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseArray
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
        # Belt scenario: each pair in one message, so that no drop can split it.
        self._pose_array_type = PoseArray
        self._pair_publisher = self.node.create_publisher(PoseArray, 'pick_place', depth)
        self._trajectories = []  # (message, system-clock time of reception [s])
        self._statuses = []  # (level, message, values) of the planner's statuses
        self._answered_trajectories = 0  # trajectories waited for by wait_until_idle()
        self._trajectory_subscription = self.node.create_subscription(
            JointTrajectory, 'joint_trajectory', self._on_trajectory, depth)
        # /diagnostics is shared by every node of the domain: keep a longer queue.
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                      100)
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self.node)

    def _on_trajectory(self, message, info):
        """Keep a trajectory with the time the middleware received it."""
        # The callback may run some milliseconds later (this process also plans): the
        # middleware's reception time is when the controller, another subscriber, has it.
        received = info.get('received_timestamp', 0) * 1e-9
        self._trajectories.append((message, received or time.time()))

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

    def spin_until(self, condition, timeout):
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
                    and self._pair_publisher.get_subscription_count() > 0
                    and self._trajectory_subscription.get_publisher_count() > 0
                    and any(info.node_name == name and info.node_namespace == namespace
                            for info in self.node.get_publishers_info_by_topic('/diagnostics')))

        if not self.spin_until(matched, timeout):
            return EXIT_TIMEOUT, (f'{name} and the cell did not discover each other within '
                                  f'{timeout:g} s')
        return None

    @property
    def config(self):
        """Return the planner's PlannerConfig."""
        return self._settings.planner

    def now_ns(self):
        """Return the node clock's time [ns] (the clock of the stamps)."""
        return self.node.get_clock().now().nanoseconds

    def statuses(self):
        """Return the planner's statuses so far, as (level, message, values), in order."""
        return list(self._statuses)

    def received_messages(self):
        """Return the trajectory messages received, as (message, reception time [s])."""
        return list(self._trajectories)

    def send_pick_place(self, pick, place, stamp_ns):
        """Publish one pair as a ``pick_place`` PoseArray stamped ``stamp_ns`` (node clock)."""
        from builtin_interfaces.msg import Time

        stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
        message = self._pose_array_type()
        message.header.frame_id = self._settings.frame_id
        message.header.stamp = stamp
        message.poses = [self._pose(pick, stamp).pose, self._pose(place, stamp).pose]
        self._pair_publisher.publish(message)

    def _pose(self, position, stamp):
        """Return a PoseStamped at ``position`` in the node's frame, level orientation."""
        message = self._pose_type()
        message.header.frame_id = self._settings.frame_id
        message.header.stamp = stamp
        point = message.pose.position
        point.x, point.y, point.z = (float(value) for value in position)
        message.pose.orientation.w = 1.0
        return message

    def send_pair(self, outcome, timeout):
        """
        Send one pair and wait for the node's answer (not for its trajectory).

        Fills in ``outcome`` (sent time, answer level, message, values, round trip); returns
        False when the pick was not taken or no answer came within ``timeout`` seconds.
        """
        first_status = len(self._statuses)
        # One stamp for both poses: they pair in the 'stamp' pairing mode too.
        stamp = self.node.get_clock().now().to_msg()
        pending = self._planner.pending_pick_count
        self._pick_publisher.publish(self._pose(outcome.pick, stamp))

        # Pick and place travel on separate topics and could overtake each other: send the
        # place only once the node holds the pick or has said why it does not.
        def pick_taken():
            return (self._planner.pending_pick_count != pending
                    or any(values.get('topic') == 'pick_pose'
                           for _, _, values in self._statuses[first_status:]))

        if not self.spin_until(pick_taken, timeout):
            return False
        first_status = len(self._statuses)
        outcome.sent_time = time.time()
        sent = time.perf_counter()
        self._place_publisher.publish(self._pose(outcome.place, stamp))

        # The answer is the 'planned' status or the place's rejection; other statuses
        # (warnings, news of earlier pairs such as their release) are not it.
        def answer():
            return next(((level, message, values)
                         for level, message, values in self._statuses[first_status:]
                         if (level == 'OK' and message == PLANNED_MESSAGE)
                         or (level == 'ERROR' and values.get('topic') == 'place_pose')),
                        None)

        if not self.spin_until(lambda: answer() is not None, timeout):
            return False
        outcome.round_trip = time.perf_counter() - sent
        outcome.level, outcome.message, outcome.values = answer()
        return True

    def _busy_until(self):
        """Predicted end of the last trajectory received [s] (system clock), or None."""
        if not self._trajectories:
            return None
        message, received = self._trajectories[-1]
        stamp = message.header.stamp.sec + 1e-9 * message.header.stamp.nanosec
        last = message.points[-1].time_from_start if message.points else None
        duration = 0.0 if last is None else last.sec + 1e-9 * last.nanosec
        return (stamp or received) + duration

    def wait_until_idle(self, timeout, margin):
        """
        Wait for the trajectory of the pair just planned, then until it has ended.

        Returns False when the trajectory did not come within ``timeout`` seconds.
        """
        expected = self._answered_trajectories + 1
        if not self.spin_until(lambda: len(self._trajectories) >= expected, timeout):
            return False
        self._answered_trajectories = expected
        idle_from = self._busy_until() + margin
        self.spin_until(lambda: time.time() >= idle_from,
                        max(0.0, idle_from - time.time()) + SPIN_STEP)
        return True

    def wait_for_trajectories(self, count, timeout, settle):
        """
        Wait until ``count`` trajectories have arrived and the last one has ended.

        Each wait for the next trajectory is bounded by ``timeout`` (a node that holds
        trajectories releases them as the robot gets through them). Then spin ``settle``
        seconds more past the predicted end, so that strays show. Returns False on a timeout.
        """
        while len(self._trajectories) < count:
            expected = len(self._trajectories) + 1
            if not self.spin_until(lambda: len(self._trajectories) >= expected, timeout):
                return False
        end = self._busy_until()
        wait = settle if end is None else max(0.0, end - time.time()) + settle
        self.spin_until(lambda: False, wait)
        return True

    def received(self):
        """Return every trajectory received, as ReceivedTrajectory, in arrival order."""
        return [self._read(message, received) for message, received in self._trajectories]

    def _read(self, message, received):
        """Return a trajectory message as ReceivedTrajectory, with the problems of its header."""
        from ellipath_ros.conversions import joint_trajectory_data

        problems = []
        if message.header.frame_id != self._settings.frame_id:
            problems.append(f'header.frame_id {message.header.frame_id!r}, expected '
                            f'{self._settings.frame_id!r}')
        if any(len(point.effort) for point in message.points):
            problems.append('effort entries (JTC rejects them without an effort interface)')
        stamp = message.header.stamp.sec + 1e-9 * message.header.stamp.nanosec
        try:
            data = joint_trajectory_data(message)
        except EllipathError as error:
            data = None
            problems.append(f'malformed: {error}')
        return ReceivedTrajectory(data, stamp, received, tuple(problems))
