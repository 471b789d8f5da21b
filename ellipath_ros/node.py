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
``ellipath_node``: plans one pick-and-place cycle per pick/place pose pair.

Interface (topic names are relative and remappable):

* subscribes ``pick_pose`` and ``place_pose`` (geometry_msgs/PoseStamped) and, optionally,
  ``joint_states`` (sensor_msgs/JointState);
* publishes ``joint_trajectory`` (trajectory_msgs/JointTrajectory, for ros2_control's
  joint_trajectory_controller), ``/diagnostics`` (diagnostic_msgs/DiagnosticArray, one status
  per request) and ``~/path_markers`` (visualization_msgs/MarkerArray).

Only the position of a pose is used: the Delta robot has three translational degrees of
freedom and its effector stays level, so the orientation is ignored. Poses must be in the
``frame_id`` frame (there is no tf2 lookup) and have finite coordinates.

Pairing (parameter ``pairing``): ``sequence`` pairs a place with the pending pick, and a
second pick before its place replaces the first; ``stamp`` pairs a place with the pick of
identical ``header.stamp``, up to ``queue_depth`` picks waiting. A place with no pick is
rejected. Either way a place consumes its pick, whether the pair is planned or rejected.

The motion starts where the robot is: the forward kinematics of the latest ``joint_states``
(joints found by name) if it arrived within ``joint_state_timeout``, else the end of the last
published trajectory, else ``home_position``.

A rejected request publishes no trajectory, logs the reason at WARN and publishes an ERROR
diagnostics status carrying it; the node keeps serving. Parameters can be changed at run time;
every change is validated together with all the other current values, and an invalid change
is refused with its reason while the previous configuration stays in force.
"""

from collections import OrderedDict
import os
import signal
import sys
import threading
import time
import traceback

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from ellipath_ros.conversions import diagnostic_array
from ellipath_ros.conversions import joint_positions_by_name
from ellipath_ros.conversions import joint_trajectory_data
from ellipath_ros.conversions import joint_trajectory_message
from ellipath_ros.conversions import path_markers
from ellipath_ros.conversions import pose_position
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import require_point
from ellipath_ros.core.joint_trajectory import validate_jtc
from ellipath_ros.core.kinematics import check_reachable
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.parameters import build_settings
from ellipath_ros.parameters import PARAMETER_NAMES
from ellipath_ros.parameters import PARAMETER_TABLE
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.executors import MultiThreadedExecutor
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

NODE_NAME = 'ellipath_node'

# Threads of the executor in main(): one per callback group (planning, joint states, and the
# default group that serves the parameter services), so neither joint states nor parameter
# requests wait behind a plan, and a plan waits for nothing but the GIL.
EXECUTOR_THREADS = 3
# How long shutdown waits for a plan in progress before destroying the node [s].
SHUTDOWN_WAIT = 5.0
# Longest wait of the executor in main() [s]: a stop request is seen at least this often.
SPIN_PERIOD = 0.1
# At shutdown, how long each publisher may take to have its last messages acknowledged [s].
FLUSH_WAIT = 0.5
# After a signal, the process ends this soon even if the orderly shutdown is stuck [s].
STOP_DEADLINE = SHUTDOWN_WAIT + 3.0


class UnpairedPlaceError(EllipathError):
    """A place pose arrived with no pick pose to pair it with."""

    kind = 'unpaired'


class PosePairing:
    """
    Pick positions waiting for their place, at most ``depth`` of them.

    Not thread-safe: the node uses it from one mutually exclusive callback group only.
    Pending picks are dropped when the pairing mode changes.
    """

    def __init__(self):
        self._pending = OrderedDict()
        self._mode = 'sequence'

    def __len__(self):
        """Return the number of pending picks."""
        return len(self._pending)

    def _key(self, stamp, mode):
        """Return the key pairing a pick and a place in ``mode``."""
        if mode != self._mode:
            self._pending.clear()
            self._mode = mode
        return None if mode == 'sequence' else (stamp.sec, stamp.nanosec)

    def add_pick(self, stamp, position, mode, depth):
        """Store a pick; return a warning if it displaced another pick, else None."""
        key = self._key(stamp, mode)
        warning = None
        if key in self._pending:
            del self._pending[key]
            warning = ('pick_pose replaced the pending pick, which had no place_pose yet'
                       if key is None else
                       f'pick_pose replaced the pending pick of the same stamp {key}')
        elif len(self._pending) >= depth:
            dropped, _ = self._pending.popitem(last=False)
            warning = (f'pick queue full ({depth} waiting): dropped the oldest pick '
                       f'(stamp {dropped})')
        self._pending[key] = position
        return warning

    def take_pick(self, stamp, mode):
        """Remove and return the pick position paired with a place, or raise."""
        key = self._key(stamp, mode)
        try:
            return self._pending.pop(key)
        except KeyError:
            wanted = 'a pending pick_pose' if key is None else f'a pick_pose with stamp {key}'
            raise UnpairedPlaceError(
                f'place_pose: expected {wanted} to pair with (pairing {mode}), got none'
            ) from None


class EllipathNode(Node):
    """
    ROS 2 node that turns pick/place pose pairs into joint trajectories.

    Parameters
    ----------
    **node_options
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``,
        ``cli_args``, ...).

    Raises
    ------
    ellipath_ros.core.errors.EllipathError
        The start-up parameters are invalid as a whole.
    rclpy.exceptions.ParameterException
        A start-up parameter has the wrong type or is out of its range.

    """

    def __init__(self, **node_options):
        super().__init__(NODE_NAME, **node_options)
        declared = self.declare_parameters(
            '', [(spec.name, spec.default, spec.descriptor()) for spec in PARAMETER_TABLE])
        self._settings = build_settings({parameter.name: parameter.value
                                         for parameter in declared})
        # A change is validated before it is stored and applied once it is: rclpy may still
        # refuse it after our check (another on-set callback, e.g. use_sim_time's).
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._pairing = PosePairing()
        # Held while a request is served, so shutdown can wait for a plan in progress.
        self._serving = threading.Lock()
        self._latest_joint_state = None  # (JointState, time.monotonic() at arrival)
        self._last_end_position = None
        self._busy_until = None  # node-clock time the last published trajectory ends
        self._status_name = f'{self.get_name()}: plan'

        depth = self._settings.queue_depth
        # Pick and place share one mutually exclusive group: their order is kept, the pairing
        # state needs no lock and the plan runs in the place callback. Joint states have a
        # group of their own so they are stored while a plan runs.
        planning_group = MutuallyExclusiveCallbackGroup()
        self.create_subscription(PoseStamped, 'pick_pose', self._on_pick, depth,
                                 callback_group=planning_group)
        self.create_subscription(PoseStamped, 'place_pose', self._on_place, depth,
                                 callback_group=planning_group)
        self.create_subscription(JointState, 'joint_states', self._on_joint_state,
                                 qos_profile_sensor_data,
                                 callback_group=MutuallyExclusiveCallbackGroup())
        self._trajectory_publisher = self.create_publisher(
            JointTrajectory, 'joint_trajectory', depth)
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, '/diagnostics', depth)
        self._marker_publisher = self.create_publisher(MarkerArray, '~/path_markers', depth)

        planner = self._settings.planner
        self.get_logger().info(
            f'ready: poses in frame {self._settings.frame_id!r}, pairing '
            f'{self._settings.pairing}, arc_policy {planner.arc.kind}, profile '
            f'{planner.profile}, joints {list(planner.joint_names)}. Pose orientations are '
            'ignored (3-DOF Delta robot: only the position is used).')

    def wait_until_idle(self, timeout):
        """Wait up to ``timeout`` s for the request being served; return True if idle."""
        if not self._serving.acquire(timeout=timeout):
            return False
        self._serving.release()
        return True

    @property
    def pending_pick_count(self):
        """Return the number of picks waiting for their place."""
        return len(self._pairing)

    # --- parameters -----------------------------------------------------------------------

    def _current_values(self):
        """Return the current value of every parameter of the table."""
        return {name: self.get_parameter(name).value for name in PARAMETER_NAMES}

    def _validate_parameters(self, parameters):
        """Accept ``parameters`` only if, merged with the current values, the set is valid."""
        values = self._current_values()
        values.update((parameter.name, parameter.value) for parameter in parameters)
        try:
            build_settings(values)
        except EllipathError as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters):
        """Switch to the settings of the parameters just stored (validated above)."""
        self._settings = build_settings(self._current_values())
        changes = ', '.join(f'{parameter.name}={parameter.value!r}' for parameter in parameters)
        self.get_logger().info(f'parameters changed: {changes}')

    # --- subscriptions --------------------------------------------------------------------

    def _on_joint_state(self, message):
        """Remember the latest joint state and when it arrived."""
        self._latest_joint_state = (message, time.monotonic())

    def _on_pick(self, message):
        """Store a valid pick pose until its place arrives."""
        self._serve('pick_pose', self._handle_pick, message)

    def _on_place(self, message):
        """Plan and publish the cycle of a place pose and its pick."""
        self._serve('place_pose', self._handle_place, message)

    def _serve(self, topic, handler, message):
        """Run ``handler`` and turn any failure into a rejection; the node keeps serving."""
        received = time.perf_counter()
        settings = self._settings  # one consistent snapshot for the whole request
        try:
            with self._serving:
                handler(message, settings, received)
        except EllipathError as error:
            self.get_logger().warn(f'{topic} rejected: {error}')
            self._publish_status(DiagnosticStatus.ERROR, str(error),
                                 {'topic': topic, 'kind': error.kind})
        except Exception as error:  # a bug in one request must not stop the node
            self.get_logger().error(
                f'{topic}: unexpected {type(error).__name__}: {error}\n'
                f'{traceback.format_exc()}')
            self._publish_status(DiagnosticStatus.ERROR,
                                 f'internal error: {type(error).__name__}: {error}',
                                 {'topic': topic, 'kind': 'internal'})

    def _checked_position(self, topic, message, settings):
        """Return the position of a pose in the base frame, or raise naming the problem."""
        frame_id = message.header.frame_id
        if frame_id != settings.frame_id:
            raise InvalidInputError(
                f'{topic}.header.frame_id: expected {settings.frame_id!r} (no tf2: poses must '
                f'be in the robot base frame), got {frame_id!r}')
        return require_point(f'{topic}.pose.position', pose_position(message))

    def _handle_pick(self, message, settings, received):
        """Validate a pick pose and queue it."""
        position = self._checked_position('pick_pose', message, settings)
        check_reachable(position, settings.planner.geometry, name='pick_pose.pose.position')
        warning = self._pairing.add_pick(message.header.stamp, position, settings.pairing,
                                         settings.queue_depth)
        if warning is not None:
            self.get_logger().warn(warning)
            self._publish_status(DiagnosticStatus.WARN, warning,
                                 {'topic': 'pick_pose', 'pending_picks': len(self._pairing)})

    def _handle_place(self, message, settings, received):
        """Pair a place pose with its pick, plan, check and publish the trajectory."""
        pick = self._pairing.take_pick(message.header.stamp, settings.pairing)
        place = self._checked_position('place_pose', message, settings)
        now = self.get_clock().now()
        # While the last trajectory still runs, the robot is not where it will start: plan
        # from that trajectory's end and stamp this one to start when it ends (JTC keeps
        # executing the running trajectory until the new one's start time).
        queued = self._busy_until is not None and self._busy_until > now
        if queued:
            start, start_source = self._last_end_position, 'last_trajectory'
        else:
            start, start_source = self._start_position(settings)
        plan = plan_cycle(start, pick, place, settings.planner, pick_dwell=settings.pick_dwell,
                          place_dwell=settings.place_dwell)
        start_time = self._busy_until if queued else self.get_clock().now()
        stamp = start_time.to_msg() if queued or settings.header_stamp == 'now' else Time()
        trajectory = joint_trajectory_message(plan.joint_trajectory, settings.frame_id, stamp)
        # Check what is actually sent, after the conversion to whole nanoseconds.
        validate_jtc(joint_trajectory_data(trajectory),
                     expect_names=settings.planner.joint_names)
        self._trajectory_publisher.publish(trajectory)
        latency = time.perf_counter() - received
        self._last_end_position = plan.end_position
        # A zero stamp starts on receipt: the trajectory ends about its duration from now.
        self._busy_until = start_time + Duration(seconds=plan.metrics['duration'])

        values = dict(plan.metrics)  # its plan_time is the planning latency
        values.update(receive_to_publish_latency=latency, start_source=start_source,
                      queued_after_last_trajectory=str(queued).lower())
        self._publish_status(DiagnosticStatus.OK, 'planned', values)
        if self._marker_publisher.get_subscription_count() > 0:
            self._marker_publisher.publish(path_markers(plan, settings.frame_id, stamp))
        self.get_logger().debug(
            f'planned {len(trajectory.points)} points, receive to publish {latency * 1e3:.2f} ms')

    def _start_position(self, settings):
        """Return the TCP start of the next cycle and where it comes from."""
        latest = self._latest_joint_state
        if latest is not None:
            joint_state, arrival = latest
            if time.monotonic() - arrival <= settings.joint_state_timeout:
                joints = joint_positions_by_name(joint_state, settings.planner.joint_names)
                if joints is not None:
                    position = forward_kinematics(joints, settings.planner.geometry,
                                                  name='joint_states.position')
                    return position, 'joint_states'
                self.get_logger().warn(
                    f'joint_states lacks a finite position of {list(settings.planner.joint_names)}'
                    ': not used as the start', throttle_duration_sec=10.0)
        if self._last_end_position is not None:
            return self._last_end_position, 'last_trajectory'
        return settings.home_position, 'home_position'

    def _publish_status(self, level, message, values):
        """Publish one diagnostics status about the current request."""
        self._diagnostics_publisher.publish(diagnostic_array(
            self.get_clock().now().to_msg(), self._status_name,
            self.get_fully_qualified_name(), level, message, values))


def _watch_signals(stop, finished):
    """
    Make SIGINT and SIGTERM set ``stop``; exit if ``finished`` is not set STOP_DEADLINE later.

    rclpy's own handlers are not used (see main()): they shut the context down at once, from
    a thread of their own, while a plan may still be publishing, and they rely on waking the
    executor's wait, a wake-up that is sometimes lost. Python runs a signal handler only in
    the main thread, between two bytecodes; the main thread spends its time in rcl_wait. So
    a thread of its own learns of the signal from the wake-up file descriptor, which the
    C-level handler writes in whichever thread takes the signal, sets ``stop`` and, should
    the orderly shutdown of main() not finish in time, ends the process.
    """
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)
    signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda signum, frame: stop.set())

    def watch():
        os.read(read_fd, 1)
        stop.set()
        if not finished.wait(STOP_DEADLINE):
            get_logger(NODE_NAME).error(
                f'shutdown not finished {STOP_DEADLINE:g} s after the signal: exiting now')
            os._exit(0)

    threading.Thread(target=watch, name='signal_watch', daemon=True).start()


def main(args=None):
    """
    Run ``ellipath_node`` until SIGINT or SIGTERM; return the process exit code.

    A signal stops the node within ``SPIN_PERIOD``: the plan in progress (if any) is finished
    and published (up to ``SHUTDOWN_WAIT``), then the node and the context are shut down, and
    the exit code is 0. If that is not done ``STOP_DEADLINE`` after the signal, an error is
    logged and the process exits with status 0 anyway.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments (``--ros-args ...``); ``sys.argv`` if None.

    """
    # Why not rclpy's signal handlers and executor.spin(): the node sometimes ignored the first
    # SIGINT (docs/reliability.md). A process started in the background of a non-interactive
    # shell (`cmd &`, scripts) inherits SIGINT ignored, so rclpy's handler has no Python
    # handler to chain to and no KeyboardInterrupt is raised (for SIGTERM there never is one).
    # The node then only stops when spin() sees that rclpy's signal thread shut the context
    # down. That thread first triggers the executor's guard condition, then shuts the context
    # down: a main thread woken in between sees the context still ok and waits again, without
    # a timeout, for ever. Here a signal only sets `stop` (also from a thread of its own, see
    # _watch_signals), the executor never waits longer than SPIN_PERIOD, this thread shuts
    # down in order, and should that not finish within STOP_DEADLINE, the process exits.
    stop = threading.Event()
    finished = threading.Event()
    _watch_signals(stop, finished)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    # Multi-threaded so that joint states and parameter services are served while a plan runs
    # (see EXECUTOR_THREADS); plans themselves stay serialised by their callback group.
    executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS)
    node = None
    exit_code = 0
    try:
        node = EllipathNode()
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_PERIOD)
    except ExternalShutdownException:
        pass
    except (EllipathError, ParameterException) as error:
        get_logger(NODE_NAME).fatal(f'invalid parameters: {error}')
        exit_code = 1
    finally:
        executor.shutdown()
        if node is not None:
            # The executor does not wait for callbacks still running in its threads.
            node.wait_until_idle(SHUTDOWN_WAIT)
            # A trajectory published just before the stop must still reach its subscribers: a
            # large one leaves in fragments after publish() returns.
            for publisher in node.publishers:
                publisher.wait_for_all_acked(Duration(seconds=FLUSH_WAIT))
            node.destroy_node()
        rclpy.try_shutdown()
        finished.set()
    return exit_code


if __name__ == '__main__':
    sys.exit(main())
