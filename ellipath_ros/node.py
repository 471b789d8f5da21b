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
``ellipath_node``: plans one pick-and-place cycle per pick/place pair and sequences them.

Interface (topic names are relative and remappable):

* subscribes ``pick_place`` (geometry_msgs/PoseArray holding exactly [pick, place], header
  stamp the latch time, header frame the poses' frame), ``pick_pose`` and ``place_pose``
  (geometry_msgs/PoseStamped) and, optionally, ``joint_states`` (sensor_msgs/JointState);
* publishes ``joint_trajectory`` (trajectory_msgs/JointTrajectory, for ros2_control's
  joint_trajectory_controller), ``/diagnostics`` (diagnostic_msgs/DiagnosticArray, statuses
  named ``<node>: plan``) and ``~/path_markers`` (visualization_msgs/MarkerArray);
* serves ``~/clear_queue`` (std_srvs/Trigger): drops every pair waiting or held, never the
  running trajectory.

Conveyor tracking (``conveyor_velocity`` or a fresh ``conveyor_twist``, geometry_msgs/
TwistStamped; :mod:`ellipath_ros.core.conveyor`): a pick's ``header.stamp`` is when the object
was there; the pair is planned for a known start, published stamped at it (the controller
holds the robot until then) and re-planned at release if that start has passed or the belt
changed (held pairs are planned again as soon as the planning thread sees the change); an
object the robot cannot reach inside the tracking window is rejected as ``missed``.

Only the position of a pose is used: the Delta robot has three translational degrees of
freedom and its effector stays level, so the orientation is ignored. Poses must be in the
``frame_id`` frame (there is no tf2 lookup) and have finite coordinates.

Pairing of the two pose topics (parameter ``pairing``): ``stamp`` (default) pairs a place with
the pick of identical ``header.stamp``, up to ``PENDING_PICKS`` picks waiting, so a message
lost in transport never joins a place with another pick; ``sequence`` pairs a place with the
pending pick. A place with no pick is rejected; a place consumes its pick either way. With
``stamp``, a place read before its pick (two topics keep no order) waits ``PLACE_WAIT`` for it
before it is rejected.
``pick_place`` needs no pairing.

Pre-planned approach (parameter ``preplan_approach``, static belts): a pick_pose that waits
for its place has its approach leg (from where the robot will be: the place of the last pair
queued, else the end of the running motion, else the robot at rest) planned by the planning
thread while no pair waits (:mod:`ellipath_ros.core.preplanning`); the pair then plans only
its transfer leg if it starts within ``start_tolerance`` of that leg with the same pick and
parameters. The 'planned' and 'released' statuses say whether it did
(``approach_preplanned``); every status counts the legs planned ahead (``preplan_legs``) and
the place_pose pairs that used one or not (``preplan_hits``, ``preplan_misses``).

Intake QoS (``INTAKE_QOS``): the pose topics are RELIABLE and KEEP_ALL, so DDS discards
nothing the node has not read; when the node reads slower than a sender sends, the sender's
``publish()`` blocks and then fails (back-pressure). Every message read is counted once in
the statuses' ledger (``pairs_*``, ``picks_*``; docs/reliability.md).

Sequencing (:mod:`ellipath_ros.core.sequencing`). Jazzy's joint_trajectory_controller
replaces the running trajectory at its next control cycle whatever the new ``header.stamp``
(src/joint_trajectory_controller.cpp ``update()``, lines 273-315) and splines from the
measured state to the new first point (src/trajectory.cpp ``sample()``, lines 148-168), so a
trajectory published while another runs cuts it short. The node therefore works in three
stages: the subscription callbacks only validate, pair and queue (a full queue rejects the
newest pair with a WARN status); a planning thread plans the queued pairs in arrival order
(on a moving belt, in latch order: the earliest ``header.stamp`` first),
each from the end of the motion planned before it (or, when nothing runs, from the robot:
fresh ``joint_states``, else the end of the last trajectory, else ``home_position``) and
holds them; a release thread publishes each held trajectory once the one before it has
ended (``controller_period`` after its latest start plus its duration). At release, a fresh
joint state further than ``start_tolerance`` from the trajectory's start makes the node
re-plan it from there, or drop it with an ERROR status.

Every rejection or drop publishes a status with its reason; the node keeps serving.
Parameters can be changed at run time; every change is validated together with all the other
current values, and an invalid change is refused with its reason while the previous
configuration stays in force.
"""

import collections
import dataclasses
import gc
import math
import os
import signal
import sys
import threading
import time
import traceback

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from ellipath_ros.conversions import joint_positions_by_name
from ellipath_ros.conversions import number_ranges
from ellipath_ros.conversions import path_markers
from ellipath_ros.conversions import pose_array_positions
from ellipath_ros.conversions import pose_position
from ellipath_ros.conversions import seconds_from_duration
from ellipath_ros.conversions import seconds_from_time
from ellipath_ros.conversions import serialized_diagnostic_array
from ellipath_ros.conversions import serialized_joint_trajectory
from ellipath_ros.core.compiled import warm_up
from ellipath_ros.core.conveyor import plan_belt_cycle
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import LateReleaseError
from ellipath_ros.core.errors import require_point
from ellipath_ros.core.joint_trajectory import validate_jtc
from ellipath_ros.core.kinematics import check_reachable
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.planner import plan_approach
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.preplanning import ApproachCache
from ellipath_ros.core.sequencing import check_start
from ellipath_ros.core.sequencing import PlannedMotion
from ellipath_ros.core.sequencing import PosePairing
from ellipath_ros.core.sequencing import QueueFullError
from ellipath_ros.core.sequencing import Sequencer
from ellipath_ros.executor import InlineGroupExecutor
from ellipath_ros.malloc_policy import MALLOC_TRIM_PERIOD
from ellipath_ros.malloc_policy import release_free_memory
from ellipath_ros.malloc_policy import set_malloc_policy
from ellipath_ros.parameters import build_settings
from ellipath_ros.parameters import parameter_declarations
from ellipath_ros.parameters import PARAMETER_NAMES
from geometry_msgs.msg import PoseArray
from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import TwistStamped
import numpy as np
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy
from rclpy.qos import HistoryPolicy
from rclpy.qos import qos_profile_sensor_data
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

NODE_NAME = 'ellipath_node'

# Pool threads of the executor in main(): one per callback group other than intake's (joint
# states, conveyor_twist, and the default group that serves the parameter services and
# clear_queue). Intake runs in main()'s thread itself (see ellipath_ros.executor); planning
# and release run in threads of their own, so intake never waits behind a plan.
EXECUTOR_THREADS = 3
# How long shutdown waits for the planning and release threads (a plan in progress) [s].
SHUTDOWN_WAIT = 5.0
# Longest wait of the executor in main() [s]: a stop request is seen at least this often.
SPIN_PERIOD = 0.1
# At shutdown, how long each publisher may take to have its last messages acknowledged [s].
FLUSH_WAIT = 0.5
# After a signal, the process ends this soon even if the orderly shutdown is stuck [s].
STOP_DEADLINE = SHUTDOWN_WAIT + 3.0
# QoS of the pose topics (pick_place, pick_pose, place_pose). KEEP_ALL + RELIABLE: DDS never
# discards a message the node has not read (KEEP_LAST did, silently, in a flood). The bound on
# memory is then DDS's resource limits (Fast DDS: max_samples 5000 per history by default):
# once the node's history and the sender's are full, a RELIABLE/KEEP_ALL sender's publish()
# blocks up to its max_blocking_time and then fails, so the sender knows (back-pressure).
# Senders must publish RELIABLE; KEEP_ALL too, or their own KEEP_LAST history may overwrite
# what was not yet delivered (docs/reliability.md).
INTAKE_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE, depth=1)
# History of the /diagnostics publisher (KEEP_LAST, RELIABLE): in a flood the node publishes
# a status per message read, and a writer whose history is full overwrites statuses a slow
# subscriber has not yet acknowledged. KEEP_ALL would block the node instead.
DIAGNOSTICS_DEPTH = 1000
# Most picks waiting for their place (stamp pairing; beyond it the oldest is evicted with a
# status). The executor visits pick_pose before place_pose (creation order, one mutually
# exclusive group), so in a burst picks are read ahead of their places, by up to the
# place_pose backlog in DDS (two histories of 5000, see INTAKE_QOS); picks whose place was
# never sent wait too, until evicted. A waiting pick takes about 0.3 kB.
PENDING_PICKS = 12_000
# Most picks waiting for their place, and pairs waiting for their plan, whose approach leg is
# planned ahead (preplan_approach); older ones are planned in one go. Only the picks whose
# place comes next can gain, and each leg kept holds its path, motion and points (0.43 MB at
# the median, 0.79 MB at most, over 39 legs of the bench's pairs, tracemalloc): a few suffice.
PREPLANNED_PICKS = 8
# Two topics keep no order between them: under load a place can be read before the pick sent
# ahead of it (2 of 900 two-topic pairs in a 30-minute soak were rejected as unpaired so). A
# place whose pick has not arrived (stamp pairing) waits this long [s] for it, then is
# rejected `unpaired` with a status (checked with the intake statuses, see STATUS_PERIOD).
PLACE_WAIT = 0.5
# The release thread polls the clock for this long before a release is due, rather than
# sleeping until then: a sleeping thread can get a core milliseconds late on a busy machine.
RELEASE_SPIN = 0.002  # s
# Each message of these topics is one pair, counted once whatever becomes of it.
PAIR_TOPICS = ('place_pose', 'pick_place')
# Intake logs at most one rejection per this period [s] and counts the others: rclpy's logger
# spends about 1.7 ms per call looking up its caller's source file, three quarters of what
# intake spent on a rejected pair, so a flood was read four times slower and DDS dropped
# what the node had not read. Every rejection still has its status on /diagnostics.
REJECTION_LOG_PERIOD = 1.0
# Intake reads up to this many pose messages per executor callback, straight from the
# subscriptions (_read_intake): rclpy's executor spends about 0.5 ms of CPU per callback
# (building its wait set, a task, a hand-over to a pool thread), five times what taking and
# checking a pair costs, and in a flood the node read no more than about 200 pairs/s. Bounded,
# so that the executor still serves the status timer of the same callback group in between.
INTAKE_BATCH = 100
# Intake statuses (rejections, dropped picks) are published together, at most one
# /diagnostics message per this period [s] (a lone rejection at once), and the pairs a full
# queue rejects in one period share one status that names them all: one DiagnosticArray per
# pair cost 0.25 ms, more than half of what intake spent on a rejected pair.
STATUS_PERIOD = 0.1
# How often a blocked worker thread looks whether the node stops [s].
WORKER_POLL = 0.1
# The interpreter's thread switch interval [s]: the release thread wakes at a trajectory's
# end, but needs the GIL, which a planning thread in NumPy code keeps for up to the switch
# interval (5 ms by default): 0.5 ms bounds that delay of the release.
SWITCH_INTERVAL = 0.0005
# NumPy's cache of small freed blocks (numpy/_core/src/multiarray/alloc.c: NBUCKETS,
# NCACHE_DATA, NBUCKETS_DIM / 2, NCACHE_DIM): data blocks below this many bytes, this many of
# each size; shape and strides blocks of arrays of rank below this, this many of each rank.
# See fill_numpy_cache.
NUMPY_CACHE_BYTES = 1024
NUMPY_CACHE_DEPTH = 7
NUMPY_DIMENSION_CACHE_RANKS = 8
NUMPY_DIMENSION_CACHE_DEPTH = 15
# A belt pick starts at a time planned in advance (the intercept depends on it): at least this
# many times the median duration of the last BELT_PLAN_TIMES belt plans (missed ones
# included) after the plan starts (while idle), never less than BELT_LEAD_MIN, and
# BELT_START_MARGIN after the motion queued before it, which absorbs the release thread's
# delay, so that the planned start is still ahead at release. The median, over every attempt:
# with the last successful plan's duration alone, one slow plan (1.5 s) set a 3 s lead that
# made every later object missed, and missed plans never lowered it again.
BELT_LEAD_FACTOR = 2.0
BELT_PLAN_TIMES = 5
BELT_LEAD_MIN = 0.1  # s
BELT_START_MARGIN = 0.02  # s
# The duration of a belt plan assumed before the first one has been timed [s].
BELT_PLAN_TIME_GUESS = 0.5
# A belt pick started later by shortening its initial wait keeps at least this much of it [s].
MIN_WAIT_LEFT = 1e-3
# A belt pick found late when its message is about to go out is checked again (started later
# or re-planned) at most this often, then dropped with a status.
BELT_RELEASE_TRIES = 3


class OffTrajectoryError(EllipathError):
    """The robot left the running trajectory and where it stopped is not known."""

    kind = 'off_trajectory'


class EllipathNode(Node):
    """
    ROS 2 node that turns pick/place pose pairs into joint trajectories, released in turn.

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
        # Before any topic exists, so that no pair waits (or is discovered) while the planner's
        # kernels compile: seconds on the first start after an install.
        kernels_ready_s = warm_up()
        declared = self.declare_parameters('', parameter_declarations())
        self._settings = build_settings({parameter.name: parameter.value
                                         for parameter in declared})
        # A change is validated before it is stored and applied once it is: rclpy may still
        # refuse it after our check (another on-set callback, e.g. use_sim_time's).
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

        depth = self._settings.queue_depth
        self._pairing = PosePairing()
        self._sequencer = Sequencer(depth)
        self._approaches = ApproachCache(PREPLANNED_PICKS)
        # Notified on every joint state (the release thread may wait for a fresh one).
        self._joint_state_arrived = threading.Condition()
        self._latest_joint_state = None  # (JointState, time.monotonic() at arrival)
        self._last_end_position = None
        # (clock time, node-clock Time) at which the last 'ahead' trajectory ends.
        self._ahead_end = (None, None)
        self._status_name = f'{self.get_name()}: plan'
        # The statuses' hardware_id; read once, as rclpy builds it anew at each call.
        self._hardware_id = self.get_fully_qualified_name()
        # (time.monotonic() of the last intake rejection logged, rejections not logged since)
        self._rejection_log = (None, 0)
        # Intake statuses not yet published (see STATUS_PERIOD), touched only by the intake
        # callback group: statuses built, and per topic the pairs a full queue rejected with
        # the first one's reason; when they were last published (time.monotonic()).
        self._intake_statuses = []
        self._queue_full = {}  # topic: ([pair numbers], first error text)
        self._intake_published = -math.inf

        # The pose topics share one mutually exclusive group: their order is kept and the
        # pairing state needs no lock. Joint states have a group of their own so they are
        # stored while intake runs.
        # main() runs this group's callbacks in its own thread (InlineGroupExecutor).
        intake_group = self.intake_group = MutuallyExclusiveCallbackGroup()
        # Held by the intake callbacks and report_stop, so that intake is closed once
        # report_stop has run whatever thread an executor runs intake in (rclpy's
        # MultiThreadedExecutor's shutdown does not wait for its pool's callbacks).
        self._intake_lock = threading.RLock()
        self._intake_closed = False
        pick_place = self.create_subscription(PoseArray, 'pick_place', self._on_pick_place,
                                              INTAKE_QOS, callback_group=intake_group)
        pick = self.create_subscription(PoseStamped, 'pick_pose', self._on_pick, INTAKE_QOS,
                                        callback_group=intake_group)
        place = self.create_subscription(PoseStamped, 'place_pose', self._on_place, INTAKE_QOS,
                                         callback_group=intake_group)
        # What _read_intake takes, in this order: every pick DDS holds before any place, so
        # that a place is read after the pick sent before it (stamp pairing).
        self._intake_routes = ((pick, 'pick_pose', self._take_pick),
                               (pick_place, 'pick_place', self._take_pick_place),
                               (place, 'place_pose', self._take_place))
        self.create_timer(STATUS_PERIOD, self.publish_intake_statuses,
                          callback_group=intake_group)
        self.create_subscription(JointState, 'joint_states', self._on_joint_state,
                                 qos_profile_sensor_data,
                                 callback_group=MutuallyExclusiveCallbackGroup())
        self.create_subscription(TwistStamped, 'conveyor_twist', self._on_conveyor_twist,
                                 qos_profile_sensor_data,
                                 callback_group=MutuallyExclusiveCallbackGroup())
        self._conveyor_twist = None  # (velocity (3,), time.monotonic() at arrival)
        # The belt velocity the held motions were last checked against (planning thread).
        self._checked_belt_velocity = None
        # Durations of the last belt plans [s], missed ones included (see BELT_PLAN_TIMES).
        self._belt_plan_times = collections.deque([BELT_PLAN_TIME_GUESS],
                                                  maxlen=BELT_PLAN_TIMES)
        self.create_service(Trigger, '~/clear_queue', self._on_clear_queue)
        self._trajectory_publisher = self.create_publisher(
            JointTrajectory, 'joint_trajectory', depth)
        self._diagnostics_publisher = self.create_publisher(
            DiagnosticArray, '/diagnostics', DIAGNOSTICS_DEPTH)
        self._marker_publisher = self.create_publisher(MarkerArray, '~/path_markers', depth)

        # When the planning thread last gave glibc's free pages back (see MALLOC_TRIM_PERIOD).
        self._trimmed = -math.inf
        # Daemon threads: a plan still running after SHUTDOWN_WAIT cannot keep the process.
        self._workers = [threading.Thread(target=loop, name=f'{NODE_NAME}{loop.__name__}',
                                          daemon=True)
                         for loop in (self._planning_loop, self._release_loop)]
        for worker in self._workers:
            worker.start()
        # Whoever shuts the context down (a signal, rclpy.shutdown), the threads stop using it.
        self.context.on_shutdown(self._sequencer.stop)

        planner = self._settings.planner
        self.get_logger().info(f'planner kernels compiled or loaded in {kernels_ready_s:.2f} s')
        self.get_logger().info(
            f'ready: poses in frame {self._settings.frame_id!r}, pairing '
            f'{self._settings.pairing}, header_stamp {self._settings.header_stamp}, '
            f'queue_depth {depth}, arc_policy {planner.arc.kind}, profile {planner.profile}, '
            f'joints {list(planner.joint_names)}. Pose orientations are ignored (3-DOF Delta '
            'robot: only the position is used).')

    def request_stop(self):
        """Make the planning and release threads stop; nothing is released from now on."""
        self._sequencer.stop()
        # The status timer is not cancelled here: this runs in the signal watcher's thread,
        # and an executor that has already taken the timer as ready then calls a cancelled
        # timer, which raises RCLError ('timer is canceled') out of spin_once (a SIGINT right
        # after start-up exited with status 1). Once stopped, its callback does nothing.

    def report_stop(self, timeout=SHUTDOWN_WAIT):
        """
        Give each pair and place still in the node at the stop its status, with the ledger.

        Called once the workers have stopped and the executor is shut down (main()): the pairs
        waiting, held, or dropped by a worker after the stop are dropped as ``stopped``, the
        places waiting for their pick rejected as ``unpaired``, and the intake statuses not
        yet published go out with one final status naming them (``pairs``) and the picks
        left waiting for their place. Waits up to ``timeout`` for an intake callback still
        running in the executor's pool (rclpy's executor shutdown does not wait for them).
        """
        if not self._intake_lock.acquire(timeout=timeout):
            self.get_logger().error(
                f'stop: intake still busy after {timeout:g} s: queued pairs not reported')
            return
        try:
            self._intake_closed = True
            self._pairing.expire_all_places('before the node stopped')
            self._expire_places()
            dropped = sorted(self._sequencer.take_dropped_while_stopped()
                             + self._sequencer.clear('stopped'))
            picks = self._pairing.counts()['pending']
            values = {'topic': 'stop', 'kind': 'stopped'}
            if dropped:
                values.update(pairs=number_ranges(dropped), pair_count=len(dropped))
            self._intake_status(
                DiagnosticStatus.WARN if dropped or picks else DiagnosticStatus.OK,
                f'stopped: {len(dropped)} pairs dropped, not released'
                + (f' (pairs {values["pairs"]})' if dropped else '')
                + f'; {picks} picks waiting for their place dropped', values)
            self.publish_intake_statuses(final=True)
        finally:
            self._intake_lock.release()

    def stop_workers(self, timeout=SHUTDOWN_WAIT):
        """Stop the planning and release threads; wait up to ``timeout`` s for each."""
        self.request_stop()
        for worker in self._workers:
            if worker is not threading.current_thread():
                worker.join(timeout)

    def destroy_node(self):
        """Stop the planning and release threads (waiting for a plan in progress), then destroy."""
        self.stop_workers()
        return super().destroy_node()

    @property
    def pending_pick_count(self):
        """Return the number of picks waiting for their place."""
        return len(self._pairing)

    @property
    def sequencer(self):
        """Return the cycle queue (:class:`ellipath_ros.core.sequencing.Sequencer`)."""
        return self._sequencer

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
        # A leg planned ahead with other parameters is never reused (the settings differ).
        self._approaches.clear()
        changes = ', '.join(f'{parameter.name}={parameter.value!r}' for parameter in parameters)
        self.get_logger().info(f'parameters changed: {changes}')

    # --- intake (subscription callbacks: validate, pair, queue; nothing slow) --------------

    def _on_joint_state(self, message):
        """Remember the latest joint state and when it arrived."""
        with self._joint_state_arrived:
            self._latest_joint_state = (message, time.monotonic())
            self._joint_state_arrived.notify_all()

    def _on_conveyor_twist(self, message):
        """Remember the belt velocity of a finite conveyor_twist and when it arrived."""
        linear = message.twist.linear
        velocity = np.array([linear.x, linear.y, linear.z], dtype=float)
        if not np.all(np.isfinite(velocity)):
            self.get_logger().warn(f'conveyor_twist: expected a finite linear velocity, got '
                                   f'{velocity.tolist()}: ignored', throttle_duration_sec=10.0)
            return
        self._conveyor_twist = (velocity, time.monotonic())

    def _conveyor(self, settings):
        """Return the belts now: conveyor_velocity, or a fresh conveyor_twist's velocity."""
        twist = self._conveyor_twist
        if twist is None or time.monotonic() - twist[1] > settings.conveyor_twist_timeout:
            return settings.conveyor
        return dataclasses.replace(settings.conveyor, velocity=twist[0])

    def _latch_time(self, stamp):
        """Return a pick's header.stamp [s] on the node clock; zero means now (on receipt)."""
        seconds = seconds_from_time(stamp)
        return seconds if seconds > 0.0 else self.get_clock().now().nanoseconds * 1e-9

    def _on_pick(self, message):
        """Store a valid pick pose until its place arrives; read what else is waiting."""
        self._read_intake(self._intake_routes[0], message)

    def _on_place(self, message):
        """Pair a place pose with its pick and queue the pair; read what else is waiting."""
        self._read_intake(self._intake_routes[2], message)

    def _on_pick_place(self, message):
        """Queue the pair of a pick_place message; read what else is waiting."""
        self._read_intake(self._intake_routes[1], message)

    def _read_intake(self, route, message):
        """Read intake as _read_batch does, unless report_stop has closed it."""
        with self._intake_lock:
            if self._intake_closed:
                self.get_logger().warn(f'{route[1]}: read after the stop was reported: not '
                                       'counted')
                return
            self._read_batch(route, message)

    def _read_batch(self, route, message):
        """
        Handle ``message`` (of ``route``), then up to INTAKE_BATCH more that DDS holds.

        Picks first: every pick waiting is read before a place or a pick_place is handled,
        the executor's own ``message`` included, so that a place's pick, sent before it, has
        been read (see _intake_routes). The executor, which would hand each message to a
        callback of its own, finds these subscriptions empty afterwards.
        """
        picks = self._intake_routes[0]
        for handled in range(1, INTAKE_BATCH + 1):
            if route is not picks:
                while (pick := _take(picks[0])) is not None:
                    self._intake(picks[1], picks[2], pick)
            self._intake(route[1], route[2], message)
            if handled == INTAKE_BATCH:
                break
            route, message = self._next_intake()
            if message is None:
                break
        if time.monotonic() - self._intake_published >= STATUS_PERIOD:
            self.publish_intake_statuses()

    def _next_intake(self):
        """Take the next pose message DDS holds, in _intake_routes' order: (route, message)."""
        for route in self._intake_routes:
            message = _take(route[0])
            if message is not None:
                return route, message
        return None, None

    def _intake(self, topic, handler, message):
        """
        Run ``handler``; turn any failure into a status. The node keeps serving.

        Every message is counted exactly once: a pair (place_pose, pick_place) by the
        sequencer, a pick_pose by the pairing (see ``pairs_*`` and ``picks_*`` in statuses).
        """
        settings = self._settings  # one consistent snapshot for the whole message
        try:
            handler(message, settings)
        except EllipathError as error:
            self._log_rejection(f'{topic} rejected: {error}')
            values = {'topic': topic, 'kind': error.kind}
            if topic in PAIR_TOPICS:
                values['pair'] = self._sequencer.reject(error.kind)
            else:
                self._pairing.reject_pick()
            self._intake_status(DiagnosticStatus.ERROR, str(error), values)
        except Exception as error:  # a bug in one message must not stop the node
            if topic in PAIR_TOPICS:
                self._sequencer.reject('internal')
            else:
                self._pairing.reject_pick()
            self._report_internal(topic, error)
        for kind, text in self._pairing.take_notices():
            self._log_rejection(text)
            self._intake_status(DiagnosticStatus.WARN, text,
                                {'topic': 'pick_pose', 'kind': kind})

    def _intake_status(self, level, message, values):
        """Keep an intake status, with the ledger as it is now, for publish_intake_statuses."""
        self._intake_statuses.append((
            self._status_name, self._hardware_id, level, message,
            {**values, **self._queue_values()}))

    def publish_intake_statuses(self, final=False):
        """
        Publish the intake statuses kept since the last call, in one /diagnostics message.

        The pairs a full queue rejected are named together, per topic, in one WARN status
        (``pairs``: their numbers as ranges; the reason given for the first one), with the
        ledger as it is now. Called by the intake callbacks and by a timer every
        STATUS_PERIOD; intake callback group only. Once stopped only the ``final`` call of
        report_stop publishes.
        """
        with self._intake_lock:
            if self._sequencer.stopped and not final:
                return  # shutting down: report_stop publishes what is kept
            self._publish_kept_statuses(final)

    def _publish_kept_statuses(self, final):
        """Publish what publish_intake_statuses publishes; the intake lock is held."""
        self._expire_places()
        self._intake_published = time.monotonic()
        statuses, self._intake_statuses = self._intake_statuses, []
        for topic, (numbers, reason) in self._queue_full.items():
            values = {'topic': topic, 'kind': QueueFullError.kind}
            if len(numbers) == 1:
                values['pair'] = numbers[0]
            else:
                values.update(pairs=number_ranges(numbers), pair_count=len(numbers))
                reason = (f'{len(numbers)} pairs rejected as {QueueFullError.kind} (pairs '
                          f'{values["pairs"]}), each in turn; the first: {reason}')
            statuses.append((
                self._status_name, self._hardware_id, DiagnosticStatus.WARN,
                reason, {**values, **self._queue_values()}))
        self._queue_full = {}
        if statuses and (final or not self._sequencer.stopped):
            self._diagnostics_publisher.publish(serialized_diagnostic_array(
                self.get_clock().now().to_msg(), statuses))

    def _log_rejection(self, text):
        """Log an intake rejection, at most one per REJECTION_LOG_PERIOD (see there)."""
        now = time.monotonic()
        last, not_logged = self._rejection_log
        if last is not None and now - last < REJECTION_LOG_PERIOD:
            self._rejection_log = (last, not_logged + 1)
            return
        if not_logged:
            text += (f' ({not_logged} more intake rejections in the last {now - last:.1f} s '
                     'not logged: each has its status on /diagnostics)')
        self._rejection_log = (now, 0)
        self.get_logger().warn(text)

    def _checked_frame(self, topic, frame_id, settings):
        """Raise unless ``frame_id`` is the robot base frame."""
        if frame_id != settings.frame_id:
            raise InvalidInputError(
                f'{topic}.header.frame_id: expected {settings.frame_id!r} (no tf2: poses must '
                f'be in the robot base frame), got {frame_id!r}')

    def _checked_point(self, name, position, settings):
        """Return a finite, reachable position or raise naming the problem."""
        position = require_point(name, position)
        check_reachable(position, settings.planner.geometry, name=name)
        return position

    def _checked_pick(self, name, position, settings):
        """Return a finite pick; reachable too, unless on a moving belt (latched upstream)."""
        if np.linalg.norm(self._conveyor(settings).velocity) > 0.0:
            # Where the robot meets it is checked along the whole planned motion.
            return require_point(name, position)
        return self._checked_point(name, position, settings)

    def _take_pick(self, message, settings):
        """Validate a pick pose and keep it for its place."""
        self._checked_frame('pick_pose', message.header.frame_id, settings)
        position = self._checked_pick('pick_pose.pose.position', pose_position(message),
                                      settings)
        # A pick it displaces is reported by _intake (PosePairing.take_notices).
        key = _stamp_key(message.header.stamp)
        held = self._pairing.add_pick(key, position, settings.pairing, PENDING_PICKS)
        for dropped in self._pairing.take_dropped_keys():
            self._approaches.discard(dropped)
        if held is not None:
            # Its place was read first and waited for it: the pair is the place's.
            place, latch_time = held
            self._submit(position, place, 'place_pose', latch_time)
        elif settings.preplan_approach and not self._conveyor(settings).moving:
            # Planned by the planning thread (none here: intake must stay quick).
            self._approaches.add(PosePairing.key(key, settings.pairing), position)
            self._sequencer.wake()

    def _take_place(self, message, settings):
        """Pair a place pose with its pick and queue the pair (or hold it for its pick)."""
        key = _stamp_key(message.header.stamp)
        pick = self._pairing.take_pick(key, settings.pairing, PLACE_WAIT, PENDING_PICKS)
        request = None
        try:
            self._checked_frame('place_pose', message.header.frame_id, settings)
            place = self._checked_point('place_pose.pose.position', pose_position(message),
                                        settings)
            # With stamp pairing the place's stamp is the pick's: the time the object was
            # there.
            latch_time = self._latch_time(message.header.stamp)
            if pick is None:
                self._pairing.hold_place(key, (place, latch_time), time.monotonic(),
                                         PLACE_WAIT)
                return
            request = self._submit(pick, place, 'place_pose', latch_time)
        finally:
            if pick is not None:
                # The pick's approach planned ahead, if any, goes with its pair; with a pair
                # rejected, away.
                self._approaches.claim(PosePairing.key(key, settings.pairing),
                                       None if request is None else request.number)

    def _submit(self, pick, place, topic, latch_time):
        """
        Queue a pair of ``topic``; return its PairRequest, or None if a full queue rejects it.

        A full queue's rejection goes into the next status.
        """
        try:
            return self._sequencer.submit(pick, place, topic, latch_time)
        except QueueFullError as error:
            self._log_rejection(f'{topic} rejected: {error}')
            numbers, _ = self._queue_full.setdefault(topic, ([], str(error)))
            numbers.append(error.pair)
            return None

    def _expire_places(self):
        """Reject, each with a status, the places whose pick did not come in PLACE_WAIT."""
        for error in self._pairing.expired_places(time.monotonic()):
            self._intake('place_pose', _raise, error)

    def _take_pick_place(self, message, settings):
        """Validate a [pick, place] PoseArray and queue the pair."""
        self._checked_frame('pick_place', message.header.frame_id, settings)
        positions = pose_array_positions(message)
        if len(positions) != 2:
            raise InvalidInputError(
                f'pick_place.poses: expected exactly 2 poses [pick, place], got '
                f'{len(positions)}')
        pick = self._checked_pick('pick_place.poses[0].position', positions[0], settings)
        place = self._checked_point('pick_place.poses[1].position', positions[1], settings)
        self._submit(pick, place, 'pick_place', self._latch_time(message.header.stamp))

    def _on_clear_queue(self, request, response):
        """Drop every pair waiting or held; the running trajectory goes on."""
        dropped = self._sequencer.clear()
        # The legs planned ahead start where the dropped pairs would have left the robot.
        self._approaches.clear()
        response.success = True
        response.message = (f'clear_queue: dropped {len(dropped)} pairs {dropped}; the '
                            'running trajectory is not touched')
        self.get_logger().info(response.message)
        self._publish_status(DiagnosticStatus.WARN if dropped else DiagnosticStatus.OK,
                             response.message,
                             {'topic': 'clear_queue', 'kind': 'cleared',
                              'dropped_pairs': ' '.join(map(str, dropped)),
                              **self._queue_values()})
        return response

    # --- planning thread ------------------------------------------------------------------

    def _planning_loop(self):
        """Plan the queued pairs in arrival (belt picks: latch) order until the node stops."""
        while not self._sequencer.stopped:
            settings = self._settings
            conveyor = self._conveyor(settings)
            self._requeue_stale_belt_picks(conveyor.velocity, settings)
            # On a moving belt, the pair latched first: the core's 'latch' order (see
            # Sequencer.take_for_planning). Planning every waiting pair to take the one whose
            # cycle ends first ('soonest') would cost a belt plan per waiting pair per pick.
            self._preplan(settings, conveyor)
            # Back for a pick to pre-plan as soon as one comes (queued pairs still first).
            taken = self._sequencer.next_to_plan(WORKER_POLL, by_latch=conveyor.moving,
                                                 until=self._approaches.wanted)
            if taken is not None:
                self._plan_queued(*taken)
                # After its statuses: the motion is already on its way (see
                # release_free_memory and MALLOC_TRIM_PERIOD).
                if time.monotonic() - self._trimmed >= MALLOC_TRIM_PERIOD:
                    release_free_memory()
                    self._trimmed = time.monotonic()

    def _requeue_stale_belt_picks(self, velocity, settings):
        """
        Plan again the held pairs planned for a belt velocity the belt no longer has.

        More than conveyor_replan_tolerance from ``velocity`` (a conveyor_twist or a parameter
        changed it; a motion planned while the belt stood still counts as planned for zero):
        put back with those held after it (Sequencer.requeue_held) and planned again while
        the robot runs, rather than at release while it waits.
        """
        if self._checked_belt_velocity is not None and np.array_equal(
                velocity, self._checked_belt_velocity):
            return  # every held motion has been checked against this velocity or planned for it
        self._checked_belt_velocity = velocity

        def stale(motion):
            planned = motion.details.get('belt_velocity', np.zeros(3))
            return float(np.linalg.norm(velocity - planned)) > settings.conveyor_replan_tolerance

        numbers = self._sequencer.requeue_held(stale)
        if numbers:
            text = (f'belt velocity now {np.round(velocity, 6).tolist()} m/s: held pairs '
                    f'{numbers} planned again')
            self.get_logger().warn(text)
            self._publish_status(DiagnosticStatus.WARN, text, {
                'kind': 'requeued', 'requeued_pairs': ' '.join(map(str, numbers)),
                **self._queue_values()})

    def _preplan(self, settings, conveyor):
        """
        Plan the approach legs of the picks waiting for their place, while no pair waits.

        Oldest pick first, each from where its pair would start now (the queue's tail, else
        the robot at rest); a leg already planned from there (within start_tolerance) with
        these settings is kept. On a moving belt none (the approach depends on the latch time
        and the belt): every leg is dropped. A failed plan is kept as failed, not reported:
        the pair's own plan reports it.
        """
        if not settings.preplan_approach or conveyor.moving:
            self._approaches.clear()
            return
        if not self._approaches.waiting_picks:
            return  # nothing to plan: not even the start is looked up
        # Each waiting pick at most once per call (a start that keeps moving, a robot moved
        # by hand, does not keep this thread here).
        for _ in range(PREPLANNED_PICKS):
            if self._sequencer.stopped or self._sequencer.waiting:
                return
            start = self._sequencer.predicted_start()
            if start is None:
                start = self._start_position(settings)[0]
            wanted = self._approaches.next_to_plan(start, settings.start_tolerance, settings)
            if wanted is None:
                return
            slot, pick = wanted
            try:
                approach = plan_approach(start, pick, settings.planner)
            except EllipathError:
                approach = None  # the pair's own plan reports it, if the pair comes
            except Exception as error:  # a bug in a pre-plan must not stop the thread
                approach = None
                self._report_internal('pick_pose', error)
            self._approaches.store(slot, start, settings, approach)

    def _plan_queued(self, request, start):
        """Plan one queued pair from ``start`` (None: where the robot is) and hold it."""
        settings = self._settings
        try:
            if start is None:
                start, start_source = self._start_position(settings)
            else:
                start_source = 'queue_tail'
            approach = None
            if (request.topic == 'place_pose' and settings.preplan_approach
                    and not self._conveyor(settings).moving):
                approach = self._approaches.take(request.number, request.pick, start,
                                                 settings.start_tolerance, settings)
            motion = self._plan(request, start, start_source, settings, approach=approach)
        except EllipathError as error:
            if not self._sequencer.plan_failed(error.kind):
                return  # cleared while planned: the clear_queue status names it
            self.get_logger().warn(f'pair {request.number} ({request.topic}) rejected: {error}')
            self._publish_status(DiagnosticStatus.ERROR, str(error), {
                'topic': request.topic, 'kind': error.kind, 'pair': request.number,
                **self._queue_values()})
            return
        except Exception as error:  # a bug in one plan must not stop the thread
            self._sequencer.plan_failed('internal')
            self._report_internal(request.topic, error, pair=request.number)
            return
        # plan_time: the whole plan, the message and its check included (as in 'released');
        # it replaces the metrics' own (the planner's part).
        values = {'topic': request.topic, 'pair': request.number, 'start_source': start_source,
                  'approach_preplanned': _flag(motion.details['approach_preplanned']),
                  'plan_time': motion.plan_time,
                  'receive_to_plan_latency': time.monotonic() - request.received}
        metrics = motion.details['metrics']

        def report_planned():
            # The metrics are computed here, on first read (0.1 ms at the median), after a
            # motion due at once is published. Refers to the metrics and values, not to the
            # motion, which holds this function: no cycle keeps the plan's arrays for the
            # garbage collector.
            self._publish_status(DiagnosticStatus.OK, 'planned',
                                 {**metrics, **values, **self._queue_values()})

        # Reported once, by whichever thread comes first: this one, or the release of the
        # motion, whose 'released' status must not come before it.
        motion.details['report_planned'] = _Once(report_planned)
        try:
            # A motion due at once (the robot idle) is released by this thread: waking the
            # release thread for it cost a hand-over of the GIL and of a core, 1.6 ms at the
            # median and 12 ms at p90 on the loaded machine; held and taken in one step, the
            # release thread is not even woken. Held is None if cleared while planned: the
            # clear_queue status names it.
            _, due = self._sequencer.finish_and_take(motion, _handover_rest(settings))
            if due is not None:
                self._release(due)
        finally:
            motion.details['report_planned']()

    def _plan(self, request, start, start_source, settings, belt_start=None, approach=None):
        """
        Plan a pair from ``start``; return the PlannedMotion holding its message.

        On a moving belt the plan starts at a known time (node clock, s; ``belt_start``, or
        chosen by :meth:`_belt_start`), kept in ``details['belt_start']`` for the release.
        Else ``approach``, the pair's approach leg planned ahead (from within
        start_tolerance of ``start``), is used if given: the motion then starts at its start.
        """
        started = time.perf_counter()
        conveyor = self._conveyor(settings)
        details = {}
        if conveyor.moving:
            start_time = (self._belt_start(start_source) if belt_start is None
                          else belt_start)
            try:
                plan = plan_belt_cycle(start, request.pick, request.place, settings.planner,
                                       conveyor, pick_dwell=settings.pick_dwell,
                                       place_dwell=settings.place_dwell,
                                       latch_time=request.latch_time, start_time=start_time)
            finally:
                self._belt_plan_times.append(time.perf_counter() - started)
            details = {'belt_start': start_time, 'belt_velocity': conveyor.velocity}
            approach = None
        else:
            plan = plan_cycle(start, request.pick, request.place, settings.planner,
                              pick_dwell=settings.pick_dwell, place_dwell=settings.place_dwell,
                              approach=approach, start_tolerance=settings.start_tolerance)
            if approach is not None:
                # Where the motion really starts, for the start check at release.
                start = approach.start
        message = serialized_joint_trajectory(plan.joint_trajectory, settings.frame_id)
        # Check what is actually sent, after the conversion to whole nanoseconds.
        validate_jtc(message.trajectory, expect_names=settings.planner.joint_names)
        return PlannedMotion(
            request, message.trajectory, require_point('start', start), plan.end_position,
            time.perf_counter() - started,
            details={'message': message, 'plan': plan, 'metrics': plan.metrics,
                     'start_source': start_source, 'approach_preplanned': approach is not None,
                     **details})

    def _belt_lead(self):
        """Return how far ahead of now an idle belt pick planned now starts [s]."""
        return max(BELT_LEAD_MIN, BELT_LEAD_FACTOR * float(np.median(self._belt_plan_times)))

    def _belt_start(self, start_source):
        """
        Return when a belt pick planned now will start (node clock, s).

        After the motions queued before it (their planned ends, a belt pick's exactly)
        plus ``BELT_START_MARGIN``; while idle, the planning time ahead (see BELT_LEAD_*).
        """
        now_clock = time.monotonic()
        now = self.get_clock().now().nanoseconds * 1e-9
        start = now + self._belt_lead()
        if start_source == 'queue_tail':
            queue_end = now + self._sequencer.predicted_end(now_clock) - now_clock
            tail = self._sequencer.tail_motion()
            if tail is not None and 'belt_start' in tail.details:
                queue_end = max(queue_end, tail.details['belt_start'] + tail.duration)
            start = max(start, queue_end + BELT_START_MARGIN)
        return start

    def _start_position(self, settings):
        """Return the TCP start of a cycle while the robot is at rest, and its source."""
        measured = self._measured_tcp(settings)
        if measured is not None:
            return measured[0], 'joint_states'
        if self._last_end_position is not None:
            return self._last_end_position, 'last_trajectory'
        return settings.home_position, 'home_position'

    def _measured_tcp(self, settings):
        """Return (TCP, monotonic measurement time) of the latest fresh joint state, or None."""
        latest = self._latest_joint_state
        if latest is None:
            return None
        joint_state, arrival = latest
        now = time.monotonic()
        if now - arrival > settings.joint_state_timeout:
            return None
        joints = joint_positions_by_name(joint_state, settings.planner.joint_names)
        if joints is None:
            self.get_logger().warn(
                f'joint_states lacks a finite position of {list(settings.planner.joint_names)}'
                ': not used', throttle_duration_sec=10.0)
            return None
        stamp = seconds_from_time(joint_state.header.stamp)
        # The stamp is the measurement time on the node clock; without one, the arrival.
        measured_at = arrival if stamp == 0.0 else (
            now - (self.get_clock().now().nanoseconds * 1e-9 - stamp))
        position = forward_kinematics(joints, settings.planner.geometry,
                                      name='joint_states.position')
        return position, min(measured_at, arrival)

    # --- release thread -------------------------------------------------------------------

    def _release_loop(self):
        """Publish each held trajectory once the one before it has ended, until the node stops."""
        while not self._sequencer.stopped:
            settings = self._settings
            motion = self._sequencer.wait_for_release(
                WORKER_POLL, spin=RELEASE_SPIN, handover_rest=_handover_rest(settings))
            if motion is not None:
                self._release(motion)

    def _release(self, motion):
        """Check where the robot is, re-plan if needed, publish and report a held motion."""
        settings = self._settings
        request = motion.request
        report_planned = motion.details.get('report_planned')
        try:
            motion, check = self._checked_start(motion, settings)
        except EllipathError as error:
            self._drop_at_release(request, error.kind, str(error))
            return
        except Exception as error:  # a bug in one release must not stop the thread
            self._sequencer.release_failed('internal')
            self._report_internal(request.topic, error, pair=request.number)
            return
        if self._sequencer.stopped:  # shutting down: nothing new is sent to the robot
            self._sequencer.release_failed('stopped')
            return
        message = motion.details['message']
        belt_start = motion.details.get('belt_start')
        if belt_start is not None:
            try:
                released = self._release_belt(motion, settings)
            except EllipathError as error:
                self._drop_at_release(request, error.kind, str(error))
                return
            if released is None:
                self._sequencer.release_failed('stopped')
                return
            motion, published, start_time = released
            message = motion.details['message']
            header_stamp = _time_at(motion.details['belt_start'])
            release = self._sequencer.released(motion, published, 'ahead',
                                               settings.controller_period,
                                               settings.release_lead, start=start_time)
        elif settings.header_stamp == 'ahead':
            # The stamp and the node's record of it come from back-to-back clock readings.
            published = time.monotonic()
            now = self.get_clock().now()
            stamp = self._sequencer.stamp_for(published, settings.release_lead)
            end, end_time = self._ahead_end
            if stamp == end:
                # Handed over during the previous motion's dwell: it starts exactly when that
                # one ends on the controller's clock (its stamp plus its duration, in ns).
                start_time = end_time
            else:
                start_time = now + Duration(seconds=stamp - published)
            last = message.last_time_from_start
            self._ahead_end = (stamp + seconds_from_duration(last),
                               start_time + Duration(seconds=last.sec, nanoseconds=last.nanosec))
            header_stamp = start_time.to_msg()
            self._trajectory_publisher.publish(message.stamped(header_stamp))
        else:
            header_stamp = Time()
            self._trajectory_publisher.publish(message.data)
            # Read after publishing, so the latest start (this + controller_period) is not
            # underestimated by the time publish() takes.
            published = time.monotonic()
        if belt_start is None:
            release = self._sequencer.released(motion, published, settings.header_stamp,
                                               settings.controller_period,
                                               settings.release_lead)
        self._last_end_position = motion.end_position
        if report_planned is not None:
            report_planned()
        self._publish_status(DiagnosticStatus.OK, 'released',
                             self._release_values(release, check))
        if self._marker_publisher.get_subscription_count() > 0:
            self._marker_publisher.publish(path_markers(
                motion.details['plan'], settings.frame_id, header_stamp))

    def _drop_at_release(self, request, kind, error):
        """Count the pair taken for release as dropped as ``kind`` and say why."""
        self._sequencer.release_failed(kind)
        if self._sequencer.stopped:
            return  # shutting down: the context may be gone
        reason = f'pair {request.number} dropped at release: {error}'
        self.get_logger().error(reason)
        self._publish_status(DiagnosticStatus.ERROR, reason, {
            'topic': request.topic, 'kind': kind, 'pair': request.number,
            **self._queue_values()})

    def _release_belt(self, motion, settings):
        """
        Publish a belt pick whose stamp is still release_lead ahead; (motion, published, start).

        Checking the start and publishing are not one step: a release thread held up in
        between (a loaded host, a re-plan that outlasts the lead) would send a stamp already
        past, and the controller would start mid-motion, a jump. So the stamp is compared
        with the clock right before the message goes out, and a late pick is checked again
        (started later or re-planned), at most BELT_RELEASE_TRIES times. Returns None when
        the node is shutting down; raises LateReleaseError when every try was late.
        """
        for _ in range(BELT_RELEASE_TRIES):
            motion = self._checked_belt(motion, settings)
            if self._sequencer.stopped:
                return None
            released = self._publish_belt(motion, settings.release_lead)
            if released is not None:
                return (motion, *released)
        raise LateReleaseError(
            f'belt start: expected its stamp at least release_lead {settings.release_lead:g} s '
            f'after publication, got it late {BELT_RELEASE_TRIES} times in a row')

    def _publish_belt(self, motion, lead):
        """
        Publish a belt pick stamped at its planned start; return (published, start) clock times.

        The controller holds the robot at the first point until the stamp, so the motion
        starts exactly when its intercept was planned for. Nothing is published, and None
        returned, when the stamp is less than ``lead`` [s] ahead of the clock.
        """
        belt_start = motion.details['belt_start']
        published = time.monotonic()
        now = self.get_clock().now()
        start_ns = _nanoseconds(belt_start)
        if start_ns - now.nanoseconds < lead * 1e9:
            return None
        message = motion.details['message']
        self._trajectory_publisher.publish(message.stamped(_time_at(belt_start)))
        clock_start = published + (start_ns - now.nanoseconds) * 1e-9
        last = message.last_time_from_start
        last_ns = last.sec * 1_000_000_000 + last.nanosec
        self._ahead_end = (clock_start + last_ns * 1e-9,
                           now + Duration(nanoseconds=start_ns + last_ns - now.nanoseconds))
        return published, clock_start

    def _checked_belt(self, motion, settings):
        """
        Return the belt pick re-planned if its planned start has passed or the belt changed.

        A pick whose start is less than release_lead ahead, or planned for a belt velocity
        more than conveyor_replan_tolerance from the current one, is planned again from the
        same start point (its intercept depends on both); an object missed by then raises.
        """
        belt_start = motion.details.get('belt_start')
        if belt_start is None:
            return motion
        now = self.get_clock().now().nanoseconds * 1e-9
        change = np.linalg.norm(self._conveyor(settings).velocity
                                - motion.details['belt_velocity'])
        if (belt_start >= now + settings.release_lead
                and change <= settings.conveyor_replan_tolerance):
            return motion
        late = now + settings.release_lead + BELT_START_MARGIN - belt_start
        if change <= settings.conveyor_replan_tolerance:
            delayed = _delayed_belt_start(motion, late, settings.frame_id)
            if delayed is not None:
                return delayed
        reason = ('its planned start has passed' if belt_start < now + settings.release_lead
                  else f'the belt velocity changed by {change:.4g} m/s')
        self.get_logger().warn(f'pair {motion.request.number}: {reason}: re-planned')
        start = now + self._belt_lead()
        return self._plan(motion.request, motion.start_position,
                          f'replanned_{motion.details["start_source"]}', settings,
                          belt_start=start)

    def _checked_start(self, motion, settings):
        """Return (motion, StartCheck): the motion re-planned if the robot is elsewhere."""
        geometry = settings.planner.geometry
        last_release = self._sequencer.last_release
        measured = self._measured_tcp(settings)
        check = check_start(motion, last_release, *(measured or (None, 0.0)), geometry,
                            settings.start_tolerance)
        if check.action == 'wait':
            measured = self._joint_state_after(last_release.latest_end, settings)
            if measured is None:
                raise OffTrajectoryError(
                    f'joint_states: expected the robot on the running trajectory, got '
                    f'{check.distance * 1e3:.2f} mm off it and no joint state measured after '
                    f'its end within joint_state_timeout {settings.joint_state_timeout:g} s')
            check = check_start(motion, last_release, *measured, geometry,
                                settings.start_tolerance)
        if check.action == 'replan':
            self.get_logger().warn(
                f'pair {motion.request.number}: the robot is {check.distance * 1e3:.2f} mm from '
                f'the start of its trajectory ({check.basis}): re-planned from there')
            motion = self._plan(motion.request, check.position, f'replanned_{check.basis}',
                                settings)
        return motion, check

    def _joint_state_after(self, after, settings):
        """Wait up to joint_state_timeout for a joint state measured after ``after``."""
        deadline = time.monotonic() + settings.joint_state_timeout
        with self._joint_state_arrived:
            while True:
                measured = self._measured_tcp(settings)
                if measured is not None and measured[1] >= after:
                    return measured
                remaining = deadline - time.monotonic()
                if remaining <= 0.0 or self._sequencer.stopped:
                    return None
                self._joint_state_arrived.wait(remaining)

    # --- diagnostics ----------------------------------------------------------------------

    def _queue_values(self):
        """Return the queue length, the predicted end of the queue, the pair and pick ledgers."""
        now = time.monotonic()
        values = {'queue_length': len(self._sequencer),
                  'predicted_queue_end_in': self._sequencer.predicted_end(now) - now}
        values.update((f'pairs_{name}', count)
                      for name, count in self._sequencer.counts().items())
        values.update((f'picks_{name}', count) for name, count in self._pairing.counts().items())
        values['places_waiting'] = self._pairing.waiting_places
        values.update((f'preplan_{name}', count)
                      for name, count in self._approaches.counts().items())
        return values

    def _release_values(self, release, check):
        """Return the key/values of a release status."""
        motion = release.motion
        values = {'topic': motion.request.topic, 'pair': motion.request.number,
                  'start_source': motion.details['start_source'],
                  'approach_preplanned': _flag(motion.details['approach_preplanned']),
                  'start_check': check.basis,
                  'start_distance': check.distance,
                  'plan_time': motion.plan_time, 'duration': motion.duration,
                  'receive_to_publish_latency': release.published - motion.request.received,
                  'robot_waited_for_planner': _flag(release.waited_for_planner)}
        # Per belt pick: intercept time, position along the window and the margin left.
        values.update((key, value) for key, value in motion.details['metrics'].items()
                      if key.startswith('belt.'))
        gap = release.predicted_gap()
        if gap is not None:
            values.update(release_delay=release.release_delay(),
                          predicted_gap_min=gap[0], predicted_gap_max=gap[1])
        values.update(self._queue_values())
        return values

    def _report_internal(self, topic, error, **values):
        """Log an unexpected failure with its traceback and publish an ERROR status."""
        if self._sequencer.stopped:
            return  # shutting down: the context may be gone
        self.get_logger().error(
            f'{topic}: unexpected {type(error).__name__}: {error}\n{traceback.format_exc()}')
        self._publish_status(DiagnosticStatus.ERROR,
                             f'internal error: {type(error).__name__}: {error}',
                             {'topic': topic, 'kind': 'internal', **values})

    def _publish_status(self, level, message, values):
        """Publish one diagnostics status (none once the node stops)."""
        if self._sequencer.stopped:
            return
        # Serialized here: rclpy's conversion of the message object leaked (see
        # serialized_diagnostic_array).
        self._diagnostics_publisher.publish(serialized_diagnostic_array(
            self.get_clock().now().to_msg(),
            [(self._status_name, self._hardware_id, level, message, values)]))


def _delayed_belt_start(motion, delay, frame_id):
    """
    Return the belt pick started ``delay`` s later with the same motion after its wait, or None.

    A pick planned with a wait at the start (its object was upstream of the window) runs
    the same absolute motion from a later start if the wait is shortened by as much: the
    intercept holds exactly and nothing is re-planned. None when the wait is too short.
    """
    plan = motion.details['plan']
    wait = plan.intercept.wait if plan.intercept is not None else 0.0
    # Whole nanoseconds, as the points' times (see joint_trajectory.on_whole_nanoseconds).
    delay = math.ceil(delay * 1e9) * 1e-9
    if delay >= wait - MIN_WAIT_LEFT:
        return None
    trajectory = motion.trajectory
    times = trajectory.time_from_start.copy()
    times[1:] -= delay
    shortened = dataclasses.replace(trajectory, time_from_start=times)
    message = serialized_joint_trajectory(shortened, frame_id)
    metrics = {**motion.details['metrics'], 'belt.wait': wait - delay}
    # The same absolute instants, from the later start.
    for key in ('belt.pick_after_start', 'belt.place_after_start'):
        metrics[key] -= delay
    return dataclasses.replace(motion, trajectory=message.trajectory, details={
        **motion.details, 'message': message, 'metrics': metrics,
        'belt_start': motion.details['belt_start'] + delay})


class _Once:
    """Call ``function`` on the first call only; a concurrent call returns once it is done."""

    def __init__(self, function):
        self._function = function
        self._lock = threading.Lock()
        self._done = False

    def __call__(self):
        with self._lock:
            if not self._done:
                self._done = True
                self._function()


def _flag(value):
    """Return a boolean as a status value: 'true' or 'false'."""
    return 'true' if value else 'false'


def _handover_rest(settings):
    """Return the ``handover_rest`` of the release (see Sequencer.due): ``ahead`` stamps only."""
    return settings.release_lead if settings.header_stamp == 'ahead' else None


def _take(subscription):
    """Return the next message DDS holds for ``subscription``, or None (rclpy's executor's way)."""
    with subscription.handle:
        taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
    return None if taken is None else taken[0]


def _nanoseconds(seconds):
    """Return a node-clock time [s] in whole nanoseconds."""
    return int(round(seconds * 1e9))


def _time_at(seconds):
    """Return a node-clock time [s] as builtin_interfaces/Time (whole nanoseconds)."""
    sec, nanosec = divmod(_nanoseconds(seconds), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def _raise(error, settings):
    """Raise ``error`` (an intake handler for an error found outside a message)."""
    raise error


def _stamp_key(stamp):
    """Return a builtin_interfaces/Time as the hashable pairing key (sec, nanosec)."""
    return (stamp.sec, stamp.nanosec)


def fill_numpy_cache():
    """
    Fill NumPy's cache of small freed blocks once, so that the node's memory does not creep.

    NumPy keeps up to NUMPY_CACHE_DEPTH freed data blocks of each size below
    NUMPY_CACHE_BYTES bytes, and NUMPY_DIMENSION_CACHE_DEPTH shape blocks of each array rank
    below NUMPY_DIMENSION_CACHE_RANKS, for reuse, and never frees them (its small-block cache,
    numpy/_core/src/multiarray/alloc.c). The planner makes arrays of many sizes, so the
    cache fills slowly, with every size met for the first time: with the flood's pairs (every
    pair another geometry) the memory in use rose by about 90 bytes a plan over 3,000 plans in
    one process, and by about 14 KiB a minute in the node at 1 pair/s, while with 500 pairs
    repeated it stayed level (docs/reliability.md, "NumPy's small-block cache"). Filled at
    start-up (about 3.6 MiB, the most it can hold), it is at its bound from the first plan.
    """
    held = [np.empty(size, dtype=np.uint8) for size in range(1, NUMPY_CACHE_BYTES)
            for _ in range(NUMPY_CACHE_DEPTH)]
    held += [np.empty((1,) * rank, dtype=np.uint8)
             for rank in range(1, NUMPY_DIMENSION_CACHE_RANKS)
             for _ in range(NUMPY_DIMENSION_CACHE_DEPTH)]
    del held


def freeze_start_up_objects():
    """
    Collect once, then keep what start-up made out of the garbage collector's full passes.

    The imports (numba's compiler, rclpy, NumPy) and the warm-up leave about 130,000 objects
    that the collector tracks and that live as long as the process. A full (generation 2)
    collection goes through every one of them: 290-320 ms in the node's start-up on the loaded
    machine, and in the bench's process the largest request time of each run (318 ms, where
    its other requests took 129 ms at most). The node makes few long-lived objects after
    start-up, so such a collection comes seldom, but when it comes it stops every thread.
    ``gc.freeze`` moves them to the permanent generation, which no collection visits.
    """
    gc.collect()
    gc.freeze()


def _watch_signals(stop, finished, on_stop):
    """
    Make SIGINT and SIGTERM set ``stop``; exit if ``finished`` is not set STOP_DEADLINE later.

    The watching thread also calls ``on_stop`` at once, so that nothing new is released to the
    robot in the up to ``SPIN_PERIOD`` before the main thread sees ``stop``.

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
        on_stop()
        if not finished.wait(STOP_DEADLINE):
            get_logger(NODE_NAME).error(
                f'shutdown not finished {STOP_DEADLINE:g} s after the signal: exiting now')
            os._exit(0)

    threading.Thread(target=watch, name='signal_watch', daemon=True).start()


def main(args=None, early_signals=()):
    """
    Run ``ellipath_node`` until SIGINT or SIGTERM, then end the process with its exit code.

    A signal stops the node within ``SPIN_PERIOD``: the planning thread finishes the plan in
    progress, if any (up to ``SHUTDOWN_WAIT``), nothing more is released, the pairs and places
    still in the node get their statuses (see EllipathNode.report_stop), the messages
    published are flushed, then the node and the context are shut down, and
    the exit code is 0. If that is not done ``STOP_DEADLINE`` after the signal, an error is
    logged and the process exits with status 0 anyway.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments (``--ros-args ...``); ``sys.argv`` if None.
    early_signals : list of int, optional
        Signals taken before this module was imported (``node_entry``, the
        ``ellipath_node`` command): its handlers record them until those of
        this function are installed, then any of them stops the node at once.

    """
    # Before the node starts its threads (see malloc_policy.MALLOC_ARENA_MAX); the
    # ellipath_node command has set it already, before importing rclpy.
    set_malloc_policy()
    # Before the first plan (see fill_numpy_cache).
    fill_numpy_cache()
    # The release thread must wake at a trajectory's end even while the planning thread runs
    # NumPy code: see SWITCH_INTERVAL.
    sys.setswitchinterval(SWITCH_INTERVAL)
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
    node = None
    _watch_signals(stop, finished, lambda: node is not None and node.request_stop())
    if early_signals:
        # Read after this function's handlers replaced node_entry's: none is missed.
        get_logger(NODE_NAME).info(
            f'{signal.Signals(early_signals[0]).name} during start-up: not starting')
        stop.set()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    executor = None
    exit_code = 0
    try:
        if not stop.is_set():  # else a signal came during start-up: no node
            node = EllipathNode()
            freeze_start_up_objects()
            # Intake in this thread, the other groups in a pool (EXECUTOR_THREADS), so that
            # intake, joint states and the services are served concurrently; planning and
            # release have threads of their own.
            executor = InlineGroupExecutor([node.intake_group], EXECUTOR_THREADS)
            executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_PERIOD)
    except ExternalShutdownException:
        pass
    except (EllipathError, ParameterException) as error:
        get_logger(NODE_NAME).fatal(f'invalid parameters: {error}')
        exit_code = 1
    finally:
        if node is not None:
            # First the node's own threads (waiting for a plan in progress), so that none of
            # them publishes or logs while the executor and the context go down.
            node.stop_workers()
        if executor is not None:
            executor.shutdown()
        if node is not None and node.context.ok():
            try:
                node.report_stop()
            except Exception as error:  # a failed report must not keep the process
                get_logger(NODE_NAME).error(
                    f'stop: statuses not published: {type(error).__name__}: {error}')
        if node is not None:
            # A trajectory published just before the stop must still reach its subscribers: a
            # large one leaves in fragments after publish() returns.
            for publisher in node.publishers:
                publisher.wait_for_all_acked(Duration(seconds=FLUSH_WAIT))
            node.destroy_node()
        rclpy.try_shutdown()
        finished.set()
    # Not a return to the interpreter's exit: its finalization (module teardown, the
    # libraries' destructors) took 5 to 6 s after this point at a load average of 8, while
    # main()'s whole shutdown took 0.1 to 0.2 s, and 10 s with six nodes at a load of 11;
    # meanwhile SIGINT and SIGTERM are back at their default actions, so a node that had
    # stopped looked hung and a second SIGINT killed it (issue 13, item 5; docs/reliability.md,
    # "Signals"). Everything is shut down and flushed by now: the process ends here.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(exit_code)


if __name__ == '__main__':
    sys.exit(main())
