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
End-to-end latency: a place pose published by one process, its trajectory received by another.

``ellipath_node`` runs as a subprocess (this package's code, started as the ``ellipath_node``
command starts it, ``python -m ellipath_ros.node_entry``; the node's default parameters) in the
namespace ``/ellipath_bench_<pid>`` on the bench's ROS domain, with DDS on this host
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``). This process sends the pairs that the in-process
benchmark planned, in the same order, so the node plans the very same requests (its start is the
last place, as in-process; no joint states are published). For each pair it publishes the pick,
builds the place's message, waits ``PICK_LEAD`` (pick and place travel on separate topics and could
overtake each other), publishes the place and measures, on its steady clock, the time until its
subscription callback has the trajectory. The trajectory is taken serialized (``raw``), as it
arrived, and deserialized after the clock is read: building its Python objects (about 1.5 ms for 80
points in rclpy) is this client's cost, not the node's; a controller in C++ deserializes it in
microseconds. The next pair goes out only after that trajectory's duration and ``IDLE_MARGIN`` have
elapsed: every pair finds the robot idle, so the figure is the planner's answer to a fresh pair
(publish, DDS, plan, message, DDS, callback), never time spent waiting behind a running trajectory.
One warm-up pair (from the home position back to it) goes first and is not counted.

The node plans a pair's approach leg when its pick arrives (``preplan_approach``, on by
default), in the ``PICK_LEAD`` before the place, so the time from the place covers the
transfer leg only when that leg was ready: the number of pairs whose approach was planned
ahead (the ``approach_preplanned`` of their ``released`` status) is counted, and the time
from the pick's publication to the trajectory (``from_pick``, both legs, ``PICK_LEAD``
included) is measured beside it, so that the gain is not mistaken for a faster planner.

Beside each time, the node's own ``plan_time`` of that pair (its ``released`` status: the
plan, the message and its check, in the node, after the place arrived; with the approach
planned ahead, the transfer leg's part) gives the time spent outside the planner: intake, the
hand-overs between the node's threads, DDS both ways, this client's callback, and any wait for
an approach still being planned when the place came.
The planner may run slower in the node than in a tight loop here, which the difference keeps
apart: after the robot's idle time between pairs the caches are cold (in one process, without
ROS, the bench's first requests took 7.1-7.6 ms of thread CPU at the median back to back and
10.7-11.1 ms each after a 0.6 s sleep; in the node, the plan's wall time is its thread CPU
time within 0.4 ms at the median: it does not wait for a core).
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

import ellipath_ros
from ellipath_ros.node import NODE_NAME
import numpy as np

NAMESPACE = 'ellipath_bench'
DISCOVERY_TIMEOUT = 30.0  # s, start-up of the node process and DDS discovery
ANSWER_TIMEOUT = 10.0  # s, for one trajectory
STOP_TIMEOUT = 10.0  # s, for the node to exit after SIGINT
# Once this process sees the node's subscriptions, the node may not yet see its publishers
# (discovery runs both ways) and would miss the first pick: wait this long before sending.
DISCOVERY_SETTLE = 1.0  # s
PICK_LEAD = 0.02  # s, pick before place (the node plans the approach leg meanwhile)
IDLE_MARGIN = 0.02  # s, after the previous trajectory's end
# Longest single wait of the client's executor [s]: a message wakes it at once, and the
# step only bounds how late it sees the node's exit. At 5 ms it woke ~200 times a second for
# nothing and took 6 % of a core (0.98 s of CPU in 15 s, 2,961 spins for 24 pairs) while the
# node planned; at 0.1 s, 1.3 % (0.20 s, 254 spins).
SPIN_STEP = 0.1
# The warm-up pair goes to this offset from the home position and back.
WARM_UP_OFFSET = np.array([0.1, 0.0, 0.0])  # m
# Joint positions of the received last point and of the in-process plan agree to this.
SAME_PLAN_TOLERANCE = 1e-6  # rad
_LEVEL_ERROR = b'\x02'
_RELEASED = 'released'
_PLAN_TIME_KEY = 'plan_time'
_PREPLANNED_KEY = 'approach_preplanned'


class EndToEndError(RuntimeError):
    """The node did not start, was not discovered, or did not answer a pair."""


def measure_end_to_end(requests, home, settings, domain_id, budget_s, progress):
    """
    Measure place-published to trajectory-received times through a separate node process.

    Parameters
    ----------
    requests : list of ellipath_ros.bench.latency.Request
        Planned requests, in order (the first starts at ``home``).
    home : array_like
        The node's home position [m].
    settings : ellipath_ros.parameters.NodeSettings
        The node's default settings (frame).
    domain_id : int
        ROS domain of the node and of this client.
    budget_s : float
        Wall-time budget of the measured pairs [s] (discovery not included).
    progress : callable
        Progress reporter ``(label, count, total, finished=False)``.

    Returns
    -------
    dict
        ``times`` (list of s), ``from_pick`` (pick published -> received, s, each),
        ``plan_times`` (the node's plan_time of each, s; empty if a status was missed),
        ``preplanned`` (pairs whose approach the node planned ahead; None if a status was
        missed), ``requested``, ``budget_reached``, ``mismatched`` (received trajectories
        whose last point differs from the in-process plan's).

    Raises
    ------
    EndToEndError
        The node did not start or answer; the message has the node's last output.

    """
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    namespace = f'/{NAMESPACE}_{os.getpid()}'
    with tempfile.TemporaryFile(mode='w+') as log:
        node_process = _start_node(namespace, domain_id, log)
        context = Context()
        rclpy.init(args=[], context=context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        client = None
        try:
            client = _Client(context, namespace, settings.frame_id)
            if not client.spin_until(client.matched, DISCOVERY_TIMEOUT,
                                     lambda: node_process.poll() is None):
                raise EndToEndError(f'{NODE_NAME} was not discovered within '
                                    f'{DISCOVERY_TIMEOUT:g} s' + _tail(node_process, log))
            client.spin_until(lambda: False, DISCOVERY_SETTLE)
            home = np.asarray(home, dtype=float)
            client.send_pair(home + WARM_UP_OFFSET, home, node_process, log)
            return _measure(client, requests, budget_s, progress, node_process, log)
        finally:
            if client is not None:
                client.close()
            rclpy.try_shutdown(context=context)
            _stop(node_process)


def _measure(client, requests, budget_s, progress, node_process, log):
    """Send the requests' pairs one at a time while the robot is idle; collect the times."""
    deadline = time.perf_counter() + budget_s
    times, from_pick = [], []
    mismatched = 0
    released_before = len(client.plan_times)
    for index, request in enumerate(requests):
        if time.perf_counter() > deadline:
            break
        progress('e2e', index, len(requests))
        elapsed, since_pick, message = client.send_pair(request.pick, request.place,
                                                        node_process, log)
        times.append(elapsed)
        from_pick.append(since_pick)
        last = np.array(message.points[-1].positions)
        if not np.allclose(last, request.trajectory.positions[-1],
                           atol=SAME_PLAN_TOLERANCE):
            mismatched += 1
    progress('e2e', len(times), len(requests), finished=True)
    plan_times = client.plan_times[released_before:]
    preplanned = client.preplanned[released_before:]
    complete = len(plan_times) == len(preplanned) == len(times)
    return {'times': times, 'from_pick': from_pick,
            'plan_times': plan_times if complete else [],
            'preplanned': sum(preplanned) if complete else None,
            'requested': len(requests),
            'budget_reached': len(times) < len(requests), 'mismatched': mismatched}


def _start_node(namespace, domain_id, log):
    """Start ``ellipath_node`` (this package's code) in ``namespace``, output to ``log``."""
    env = dict(os.environ)
    package_root = str(Path(ellipath_ros.__file__).resolve().parents[1])
    env.update(ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', ROS_DOMAIN_ID=str(domain_id),
               PYTHONUNBUFFERED='1',
               PYTHONPATH=os.pathsep.join(filter(None, [package_root,
                                                        env.get('PYTHONPATH')])))
    # Run from the package's root too: ``-m`` puts the working directory first on the path, and
    # a checkout there would be another copy, whose kernels numba compiles (and caches) anew.
    # node_entry, as the ellipath_node command: its malloc policy is set before rclpy's import.
    return subprocess.Popen(
        [sys.executable, '-m', 'ellipath_ros.node_entry',
         '--ros-args', '-r', f'__ns:={namespace}'],
        env=env, stdout=log, stderr=subprocess.STDOUT, cwd=package_root)


def _tail(node_process, log, lines=10):
    """Return the node's exit status and last output lines, for an error message."""
    log.flush()
    log.seek(0)
    text = log.read().strip().splitlines()[-lines:]
    status = node_process.poll()
    state = 'still running' if status is None else f'exited with status {status}'
    return f'; the node {state}' + (':\n' + '\n'.join(text) if text else '')


def _stop(node_process):
    """Stop the node with SIGINT (as Ctrl-C would); kill it if it does not exit in time."""
    if node_process.poll() is None:
        node_process.send_signal(signal.SIGINT)
    try:
        node_process.wait(timeout=STOP_TIMEOUT)
    except subprocess.TimeoutExpired:
        node_process.kill()
        node_process.wait()


class _Client:
    """The bench's ROS side: publishes the poses, receives trajectories and statuses."""

    def __init__(self, context, namespace, frame_id):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from trajectory_msgs.msg import JointTrajectory

        self._pose_type = PoseStamped
        self._frame_id = frame_id
        self._node_name = f'{namespace}/{NODE_NAME}'
        self.node = Node('ellipath_bench_client', namespace=namespace, context=context)
        self._pick = self.node.create_publisher(PoseStamped, 'pick_pose', 10)
        self._place = self.node.create_publisher(PoseStamped, 'place_pose', 10)
        self._trajectory_type = JointTrajectory
        self._trajectory = self.node.create_subscription(
            JointTrajectory, 'joint_trajectory', self._on_trajectory, 10, raw=True)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                      100)
        self._received = []  # (serialized message, time.perf_counter() in the callback)
        self._errors = []  # messages of the node's ERROR statuses
        self.plan_times = []  # plan_time [s] of the node's 'released' statuses, in order
        self.preplanned = []  # their approach_preplanned, as booleans
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self.node)

    def _on_trajectory(self, message):
        self._received.append((message, time.perf_counter()))

    def _on_diagnostics(self, message):
        for status in message.status:
            if status.hardware_id != self._node_name:
                continue
            if bytes(status.level) == _LEVEL_ERROR:
                self._errors.append(status.message)
            elif status.message == _RELEASED:
                values = {pair.key: pair.value for pair in status.values}
                self.plan_times.append(float(values[_PLAN_TIME_KEY]))
                self.preplanned.append(values.get(_PREPLANNED_KEY) == 'true')

    def matched(self):
        """Whether the node subscribes to both poses and publishes trajectories."""
        return (self._pick.get_subscription_count() > 0
                and self._place.get_subscription_count() > 0
                and self._trajectory.get_publisher_count() > 0)

    def spin_until(self, condition, timeout, alive=lambda: True):
        """Spin until ``condition()``; False after ``timeout`` s or once ``alive()`` fails."""
        deadline = time.perf_counter() + timeout
        while not condition():
            remaining = deadline - time.perf_counter()
            if remaining < 0.0 or not alive():
                return False
            self._executor.spin_once(timeout_sec=min(remaining, SPIN_STEP))
        return True

    def _pose(self, position):
        message = self._pose_type()
        message.header.frame_id = self._frame_id
        message.pose.position.x, message.pose.position.y, message.pose.position.z = (
            float(value) for value in position)
        message.pose.orientation.w = 1.0
        return message

    def send_pair(self, pick, place, node_process, log):
        """
        Send one pair to the idle node; return its times and trajectory.

        As (place published -> received [s], pick published -> received [s], trajectory).

        Returns once the trajectory has ended (its duration and ``IDLE_MARGIN`` after its
        reception), so that the next pair finds the robot idle.
        """
        from rclpy.serialization import deserialize_message

        received, errors = len(self._received), len(self._errors)
        pick_message = self._pose(pick)
        picked = time.perf_counter()
        self._pick.publish(pick_message)
        # Built before the clock is read: this client's work, not the node's.
        place_message = self._pose(place)
        self.spin_until(lambda: False, PICK_LEAD)
        sent = time.perf_counter()
        self._place.publish(place_message)

        def answered():
            return len(self._received) > received or len(self._errors) > errors

        if not self.spin_until(answered, ANSWER_TIMEOUT, lambda: node_process.poll() is None):
            raise EndToEndError(f'no trajectory within {ANSWER_TIMEOUT:g} s of the place '
                                + _tail(node_process, log))
        if len(self._received) == received:
            raise EndToEndError(f'the node rejected a pair planned in-process: '
                                f'{self._errors[errors]}')
        data, arrival = self._received[received]
        message = deserialize_message(data, self._trajectory_type)
        duration = message.points[-1].time_from_start
        idle_at = arrival + duration.sec + 1e-9 * duration.nanosec + IDLE_MARGIN
        self.spin_until(lambda: False, max(idle_at - time.perf_counter(), 0.0))
        return arrival - sent, arrival - picked, message

    def close(self):
        """Stop the executor and destroy the node."""
        self._executor.shutdown()
        self.node.destroy_node()
