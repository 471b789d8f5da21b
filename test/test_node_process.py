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
ellipath_node as its own process (``python -m ellipath_ros.node``), driven over DDS.

The node runs with the environment of conftest.py (DDS on this host, a domain of its own) and
``config/ellipath.yaml``; the test publishes a pick and a place, receives the trajectory, then
stops the node with SIGINT and expects exit code 0 and no traceback.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
import ellipath_ros
from ellipath_ros.conversions import joint_trajectory_data
from ellipath_ros.core.joint_trajectory import validate_jtc
from geometry_msgs.msg import PoseArray
from geometry_msgs.msg import PoseStamped
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from trajectory_msgs.msg import JointTrajectory

ROS_DOMAIN_OFFSET = 1  # see conftest.py
DISCOVERY_TIMEOUT = 20.0  # s, start-up of the node process and DDS discovery
TIMEOUT = 10.0  # s, any other wait
CONFIG = Path(__file__).resolve().parents[1] / 'config'
# The directory holding the ellipath_ros package, for the child's import path.
PACKAGE_ROOT = str(Path(ellipath_ros.__file__).resolve().parents[1])
# Keeps the topics of this test session apart from another one on the same ROS domain.
NAMESPACE = f'/ellipath_process_test_{os.getpid()}'


def _start_node(env, *ros_args):
    """Start ``python -m ellipath_ros.node --ros-args ...`` in NAMESPACE, with ``env``."""
    env = dict(env)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [PACKAGE_ROOT, env.get('PYTHONPATH')]))
    return subprocess.Popen(
        [sys.executable, '-m', 'ellipath_ros.node', '--ros-args', '-r', f'__ns:={NAMESPACE}',
         *ros_args],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _stop(process, sig=signal.SIGINT):
    """Send ``sig`` and return (exit code, stdout, stderr); kill the process if it hangs."""
    if process.poll() is None:
        process.send_signal(sig)
    try:
        stdout, stderr = process.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        process.kill()
        stdout, stderr = process.communicate()
        pytest.fail(f'the node did not stop within {TIMEOUT} s of {sig.name}:\n{stderr}')
    return process.returncode, stdout, stderr


def _spin_until(executor, condition, timeout):
    """Spin ``executor`` until ``condition()`` holds; return whether it did in time."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        executor.spin_once(timeout_sec=0.05)
    return True


def _pose(x, y, z):
    """Return a PoseStamped in base_link."""
    message = PoseStamped()
    message.header.frame_id = 'base_link'
    message.pose.position.x, message.pose.position.y, message.pose.position.z = x, y, z
    message.pose.orientation.w = 1.0
    return message


def test_node_process_plans_over_dds_and_stops_cleanly_on_sigint(ros_env, ros_context):
    process = _start_node(ros_env, '--params-file', str(CONFIG / 'ellipath.yaml'))
    client = None
    try:
        client = Node('ellipath_process_test_client', context=ros_context, namespace=NAMESPACE)
        pick_publisher = client.create_publisher(PoseStamped, 'pick_pose', 10)
        place_publisher = client.create_publisher(PoseStamped, 'place_pose', 10)
        trajectories, statuses = [], []
        trajectory_subscription = client.create_subscription(
            JointTrajectory, 'joint_trajectory', trajectories.append, 10)
        client.create_subscription(
            DiagnosticArray, '/diagnostics', lambda message: statuses.extend(
                status for status in message.status
                if status.hardware_id == f'{NAMESPACE}/ellipath_node'), 10)
        executor = SingleThreadedExecutor(context=ros_context)
        executor.add_node(client)
        assert _spin_until(executor, lambda: (
            process.poll() is not None
            or (pick_publisher.get_subscription_count() > 0
                and place_publisher.get_subscription_count() > 0
                and trajectory_subscription.get_publisher_count() > 0)),
            DISCOVERY_TIMEOUT), 'the node was not discovered'
        assert process.poll() is None, 'the node exited early'

        # One side of a topic can match before the other, and a message sent in between is
        # lost: settle, and send the pair again if the node says it missed the pick.
        _spin_until(executor, lambda: False, 0.5)
        for _ in range(3):
            pick_publisher.publish(_pose(0.10, 0.05, -0.85))
            # The pick must be handled before its place; give it a head start.
            _spin_until(executor, lambda: False, 0.3)
            place_publisher.publish(_pose(-0.15, -0.10, -0.82))
            if _spin_until(executor, lambda: trajectories or any(
                    status.level == DiagnosticStatus.ERROR for status in statuses), TIMEOUT):
                if trajectories:
                    break
                statuses.clear()
        assert trajectories, [status.message for status in statuses]
        assert _spin_until(executor, lambda: any(
            status.level == DiagnosticStatus.OK for status in statuses), TIMEOUT), statuses
        validate_jtc(joint_trajectory_data(trajectories[0]),
                     expect_names=['joint_1', 'joint_2', 'joint_3'])
        executor.shutdown()
    finally:
        if client is not None:
            client.destroy_node()
        returncode, stdout, stderr = _stop(process)
    assert returncode == 0, stderr
    assert 'Traceback' not in stderr + stdout


def test_node_process_refuses_invalid_parameters_without_traceback(ros_env):
    process = _start_node(ros_env, '-p', 'joint_min:=1.0', '-p', 'joint_max:=0.5')
    try:
        process.wait(timeout=DISCOVERY_TIMEOUT)
    except subprocess.TimeoutExpired:
        pass
    returncode, stdout, stderr = _stop(process)
    assert returncode == 1
    assert 'invalid parameters' in stderr + stdout and 'joint_max' in stderr + stdout
    assert 'Traceback' not in stderr + stdout


def test_node_process_stops_cleanly_on_sigint_with_pairs_held(ros_env, ros_context):
    process = _start_node(ros_env, '--params-file', str(CONFIG / 'ellipath.yaml'))
    client = None
    try:
        client = Node('ellipath_process_test_burst', context=ros_context, namespace=NAMESPACE)
        pair_publisher = client.create_publisher(PoseArray, 'pick_place', 10)
        trajectories = []
        trajectory_subscription = client.create_subscription(
            JointTrajectory, 'joint_trajectory', trajectories.append, 10)
        executor = SingleThreadedExecutor(context=ros_context)
        executor.add_node(client)
        assert _spin_until(executor, lambda: (
            process.poll() is not None
            or (pair_publisher.get_subscription_count() > 0
                and trajectory_subscription.get_publisher_count() > 0)),
            DISCOVERY_TIMEOUT), 'the node was not discovered'
        _spin_until(executor, lambda: False, 0.5)
        for index in range(5):
            message = PoseArray()
            message.header.frame_id = 'base_link'
            message.header.stamp.sec = index + 1
            message.poses = [_pose(-0.15, -0.1 + 0.05 * index, -0.85).pose,
                             _pose(0.15, 0.1, -0.8).pose]
            pair_publisher.publish(message)
        # The first runs, the others are being planned or held: stop now.
        assert _spin_until(executor, lambda: trajectories, TIMEOUT), 'no trajectory'
        executor.shutdown()
    finally:
        if client is not None:
            client.destroy_node()
        returncode, stdout, stderr = _stop(process)
    assert returncode == 0, stderr
    assert 'Traceback' not in stderr + stdout
