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
ONE signal stops ellipath_node: exit status 0, no traceback, idle or while a plan runs.

Each case starts ``python -m ellipath_ros.node`` (the executor of main(): intake in its
thread, the other callback groups in a pool), waits for its ``ready`` log line, sends exactly
one SIGINT or SIGTERM at some moment and expects the process to end within STOP_TIMEOUT. The
idle cases run side by side, each node in a namespace of its own. In the planning case a pick
and a place are sent, the signal follows the place while the (deliberately slow) plan runs: the
node finishes the plan but releases nothing once told to stop, so the robot does not start a
new move after the stop.
The long statistical check (hundreds of runs) is scripts/signal_stop_check.py.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
import ellipath_ros
from ellipath_ros.conversions import numbers_in_ranges
from geometry_msgs.msg import PoseArray
from geometry_msgs.msg import PoseStamped
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from test_node import pose_array
from test_node import values_of
from test_node_process import _pose
from test_node_process import _spin_until
from trajectory_msgs.msg import JointTrajectory

ROS_DOMAIN_OFFSET = 2  # see conftest.py
# s, from process start to the ready line (imports, the planner's warm-up, DDS). Six nodes
# starting at once on the 2 shared cores at a load average of 11 to 13 took 35 to 37 s (each
# about 2.7 s of CPU, 20 s of wall time in warm_up alone): 30 s made the idle test fail with
# 'not ready' and an empty log. What is tested is the stop, not how fast a node starts.
START_TIMEOUT = 90.0
STOP_TIMEOUT = 10.0  # s, from the signal to the end of the process
PACKAGE_ROOT = str(Path(ellipath_ros.__file__).resolve().parents[1])
# The paper's curvature profile (legs of about 2 s) sampled every 0.1 ms: a plan long enough
# to be interrupted (the time-optimal legs, ~0.3 s, now plan in less than the 0.15 s wait).
SLOW_PLAN = ('-p', 'output_mode:=samples', '-p', 'sample_period:=0.0001',
             '-p', 'profile:=curvature', '-p', 'join:=paper')


class NodeProcess:
    """``python -m ellipath_ros.node`` in a namespace of its own, its log collected."""

    def __init__(self, env, namespace, *ros_args):
        env = dict(env)
        env['PYTHONPATH'] = os.pathsep.join(filter(None, [PACKAGE_ROOT, env.get('PYTHONPATH')]))
        self.namespace = namespace
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'ellipath_ros.node', '--ros-args', '-r',
             f'__ns:={namespace}', *ros_args],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines = []
        self.ready = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.process.stdout:
            self.lines.append(line)
            if 'ready:' in line:
                self.ready.set()

    def stop(self, sig):
        """Send ``sig`` once (None: already sent); return (exit status, log), or fail."""
        if sig is not None:
            self.process.send_signal(sig)
        try:
            self.process.wait(timeout=STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            self._reader.join(timeout=5.0)
            pytest.fail(f'{self.namespace}: still running {STOP_TIMEOUT} s after one signal:'
                        f'\n{"".join(self.lines)}')
        self._reader.join(timeout=5.0)
        return self.process.returncode, ''.join(self.lines)

    def stop_spinning(self, executor, sig, settle):
        """Send ``sig`` once, spin ``executor`` until the process ends and ``settle`` s more."""
        self.process.send_signal(sig)
        _spin_until(executor, lambda: self.process.poll() is not None, STOP_TIMEOUT)
        _spin_until(executor, lambda: False, settle)
        status, log = self.stop(None)
        assert status == 0, log
        assert 'Traceback' not in log, log

    def kill(self):
        """Kill the process if it still runs (test clean-up)."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()


# (signal, seconds after the ready line): right away, soon, and after a long idle time.
IDLE_CASES = [(signal.SIGINT, 0.0), (signal.SIGINT, 0.3), (signal.SIGINT, 1.5),
              (signal.SIGINT, 4.5), (signal.SIGTERM, 0.0), (signal.SIGTERM, 2.0)]


@pytest.mark.timeout(START_TIMEOUT + 60.0)  # the start, the longest delay and the stop
def test_one_signal_stops_an_idle_node_cleanly(ros_env):
    tag = f'ellipath_signal_test_{os.getpid()}'
    nodes = [NodeProcess(ros_env, f'/{tag}_{index}') for index in range(len(IDLE_CASES))]
    results = [None] * len(nodes)
    try:
        def run(index):
            sig, delay = IDLE_CASES[index]
            node = nodes[index]
            if not node.ready.wait(START_TIMEOUT):
                results[index] = (f'not ready after {START_TIMEOUT:g} s (load average '
                                  f'{os.getloadavg()[0]:.1f})', ''.join(node.lines))
                return
            time.sleep(delay)
            results[index] = node.stop(sig)

        threads = [threading.Thread(target=run, args=(index,)) for index in range(len(nodes))]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    finally:
        for node in nodes:
            node.kill()
    for (sig, delay), (status, log) in zip(IDLE_CASES, results):
        assert status == 0, f'{sig.name} {delay} s after ready: status {status}\n{log}'
        assert 'Traceback' not in log, f'{sig.name} {delay} s after ready:\n{log}'


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=lambda sig: sig.name)
def test_one_signal_while_planning_stops_cleanly_and_releases_nothing(ros_env, ros_context,
                                                                      sig):
    node = NodeProcess(ros_env, f'/ellipath_signal_plan_{sig.name}_{os.getpid()}', *SLOW_PLAN)
    client = Node('signal_test_client', context=ros_context, namespace=node.namespace)
    executor = SingleThreadedExecutor(context=ros_context)
    try:
        executor.add_node(client)
        picks = client.create_publisher(PoseStamped, 'pick_pose', 10)
        places = client.create_publisher(PoseStamped, 'place_pose', 10)
        received = []
        trajectories = client.create_subscription(
            JointTrajectory, 'joint_trajectory',
            lambda message: received.append(time.monotonic()), 10)
        assert node.ready.wait(START_TIMEOUT), ''.join(node.lines)
        assert _spin_until(executor, lambda: (
            picks.get_subscription_count() and places.get_subscription_count()
            and trajectories.get_publisher_count()), START_TIMEOUT), 'node not discovered'
        # A first cycle proves the topics are connected both ways (a message sent while
        # discovery is still under way can be lost); it is sent again until it arrives.
        for _ in range(3):
            picks.publish(_pose(0.10, 0.05, -0.85))
            _spin_until(executor, lambda: False, 0.3)
            places.publish(_pose(-0.15, -0.10, -0.82))
            if _spin_until(executor, lambda: received, 20.0):
                break
        assert received, 'no trajectory for the first pair'
        received.clear()
        picks.publish(_pose(-0.15, -0.10, -0.82))
        _spin_until(executor, lambda: False, 0.3)
        places.publish(_pose(0.12, -0.08, -0.88))
        _spin_until(executor, lambda: received, 0.15)
        assert not received, 'the plan ended before the signal: make it slower'
        signalled = time.monotonic()
        # Keep receiving until the process has ended: a trajectory released after the signal
        # would arrive in this window.
        node.stop_spinning(executor, sig, 0.2)
    finally:
        executor.shutdown()
        client.destroy_node()
        node.kill()
    # The plan in progress when the signal came was not released after the stop.
    assert not received, (
        f'trajectory released {received[0] - signalled:.3f} s after the signal')


def test_pairs_and_places_still_in_the_node_at_the_stop_get_their_statuses(
        ros_env, ros_context):
    node = NodeProcess(ros_env, f'/ellipath_signal_queue_{os.getpid()}', *SLOW_PLAN)
    client = Node('signal_queue_client', context=ros_context, namespace=node.namespace)
    executor = SingleThreadedExecutor(context=ros_context)
    statuses = []  # this node's statuses (/diagnostics is shared by every node of the domain)
    try:
        executor.add_node(client)
        pairs = client.create_publisher(PoseArray, 'pick_place', 10)
        picks = client.create_publisher(PoseStamped, 'pick_pose', 10)
        places = client.create_publisher(PoseStamped, 'place_pose', 10)
        received = []
        trajectories = client.create_subscription(
            JointTrajectory, 'joint_trajectory', received.append, 10)
        client.create_subscription(
            DiagnosticArray, '/diagnostics', lambda message: statuses.extend(
                status for status in message.status
                if status.hardware_id.startswith(node.namespace)), 100)
        assert node.ready.wait(START_TIMEOUT), ''.join(node.lines)
        assert _spin_until(executor, lambda: (
            pairs.get_subscription_count() and places.get_subscription_count()
            and trajectories.get_publisher_count()), START_TIMEOUT), 'node not discovered'
        for _ in range(3):  # sent again until it arrives (see the test above)
            pairs.publish(pose_array((0.10, 0.05, -0.85), (-0.15, -0.10, -0.82)))
            if _spin_until(executor, lambda: received, 20.0):
                break
        assert received, 'no trajectory for the first pair'
        # The first slow plan runs (its motion, seconds long, keeps the next one held), the
        # others wait; a pick waits for its place; the bad pair's immediate rejection carries
        # the ledger once the node has read them.
        for x in (0.0, 0.05, -0.05, 0.1):
            pairs.publish(pose_array((-0.15, -0.10, -0.82), (x, -0.08, -0.88)))
        pick = _pose(0.1, 0.1, -0.85)
        pick.header.stamp.sec = 888
        picks.publish(pick)
        pairs.publish(pose_array((0.0, 0.0, -0.85), (0.1, 0.0, -0.85), frame_id='elsewhere'))
        assert _spin_until(executor, lambda: any(
            values_of(status).get('kind') == 'invalid_input' for status in statuses),
            START_TIMEOUT), 'the bad pair was not rejected'
        place = _pose(0.1, 0.1, -0.8)  # held for its pick (stamp 777) if read before the stop
        place.header.stamp.sec = 777
        places.publish(place)
        _spin_until(executor, lambda: False, 0.1)
        node.stop_spinning(executor, signal.SIGINT, 0.5)
    finally:
        executor.shutdown()
        client.destroy_node()
        node.kill()
    final = [status for status in statuses if values_of(status).get('kind') == 'stopped']
    assert len(final) == 1, [status.message for status in statuses]
    ledger = values_of(final[0])  # the node's last status: nothing is counted after it
    assert all(int(values_of(status).get('pairs_received', 0)) <= int(ledger['pairs_received'])
               for status in statuses)
    named = set()
    for status in statuses:
        values = values_of(status)
        named.update([int(values['pair'])] if 'pair' in values else
                     numbers_in_ranges(values.get('pairs', '')))
    counted = int(ledger['pairs_received'])
    assert counted >= 6, ledger  # the first pair (sent up to 3 times), 4 pairs, the bad one
    assert set(range(1, counted + 1)) <= named, f'pairs without a status: {ledger}'
    assert ledger['pairs_queued'] == '0' and ledger['pairs_releasing'] == '0', ledger
    # At least three of the four waited behind the slow plan when the signal came.
    assert int(ledger.get('pairs_dropped_stopped', 0)) >= 3, ledger
    assert '1 picks waiting for their place dropped' in final[0].message
    assert ledger['picks_pending'] == '1' and ledger['places_waiting'] == '0', ledger


# Run by the tests below in a process of their own (the signal handlers are process-wide).
WATCH_SCRIPT = """
import os, signal, sys, threading
from ellipath_ros import node
node.STOP_DEADLINE = 0.5
stop, finished = threading.Event(), threading.Event()
node._watch_signals(stop, finished, lambda: None)
# The main thread never takes this signal: only the watch thread can see it.
signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
os.kill(os.getpid(), signal.SIGTERM)
print('stop seen' if stop.wait(5.0) else 'stop missed', flush=True)
if sys.argv[1] == 'finish':
    finished.set()
    print('finished', flush=True)
else:
    threading.Event().wait(5.0)  # a shutdown that never ends
    print('not ended', flush=True)
"""


@pytest.mark.parametrize('mode', ['finish', 'hang'])
def test_a_signal_is_seen_whichever_thread_takes_it_and_a_stuck_shutdown_still_ends(mode):
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [PACKAGE_ROOT, env.get('PYTHONPATH')]))
    result = subprocess.run([sys.executable, '-c', WATCH_SCRIPT, mode], env=env,
                            capture_output=True, text=True, timeout=30)
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr
    assert result.stdout.splitlines()[0] == 'stop seen'
    if mode == 'finish':
        assert result.stdout.splitlines()[1:] == ['finished']
        assert 'shutdown not finished' not in result.stderr
    else:
        # Ended by the watch thread 0.5 s after the signal, before the 5 s wait was over.
        assert 'not ended' not in result.stdout
        assert 'shutdown not finished 0.5 s after the signal: exiting now' in result.stderr


def _catches(pid, sig):
    """Return True when process ``pid`` has a handler of its own for ``sig`` (/proc)."""
    with open(f'/proc/{pid}/status') as status:
        for line in status:
            if line.startswith('SigCgt:'):
                return bool(int(line.split()[1], 16) >> (sig - 1) & 1)
    return False


@pytest.mark.timeout(START_TIMEOUT + 30.0)
@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=lambda sig: sig.name)
def test_one_signal_during_the_imports_stops_the_node_even_with_sigint_inherited_ignored(
        ros_env, sig):
    # The ellipath_node command's code (node_entry.main), started as `ellipath_node &` in a
    # script starts it: SIGINT ignored. The signal is sent as soon as the process catches
    # it, i.e. while the node's imports run (a second or more), before node.main exists.
    env = dict(ros_env)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [PACKAGE_ROOT, env.get('PYTHONPATH')]))
    process = subprocess.Popen(
        [sys.executable, '-c', 'import sys; from ellipath_ros.node_entry import main; '
         'sys.exit(main())', '--ros-args', '-r', f'__ns:=/ellipath_early_{os.getpid()}'],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        deadline = time.monotonic() + START_TIMEOUT
        while not _catches(process.pid, sig):
            assert process.poll() is None and time.monotonic() < deadline, 'never caught'
            time.sleep(0.005)
        process.send_signal(sig)
        log, _ = process.communicate(timeout=START_TIMEOUT)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 0, log
    assert 'Traceback' not in log, log
    assert f'{sig.name} during start-up: not starting' in log, log
    assert 'ready:' not in log, log
