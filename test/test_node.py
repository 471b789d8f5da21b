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
ellipath_node in this process, driven over real rclpy topics by a test node.

The node and a client node share one executor; every wait is a spin_once loop bounded by
TIMEOUT. The conversions are tested first, on their own.
"""

import math
import os
from pathlib import Path
import re
import time

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from ellipath_ros import node as node_module
from ellipath_ros.conversions import duration_from_seconds
from ellipath_ros.conversions import joint_positions_by_name
from ellipath_ros.conversions import joint_trajectory_data
from ellipath_ros.conversions import key_values
from ellipath_ros.conversions import seconds_from_duration
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.joint_trajectory import validate_jtc
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.node import EllipathNode
from ellipath_ros.node import PosePairing
from ellipath_ros.node import UnpairedPlaceError
from ellipath_ros.parameters import build_settings
from ellipath_ros.parameters import parameter_defaults
from geometry_msgs.msg import PoseStamped
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker
from visualization_msgs.msg import MarkerArray

ROS_DOMAIN_OFFSET = 0  # see conftest.py
TIMEOUT = 10.0  # s, longest wait for one event
SETTLE = 0.2  # s, spun after the last expected message to catch unexpected ones
PASSES = 2e-4  # m, the TCP passes through a point: knot_tolerance (0.1 mm) plus sampling
# Keeps the topics of this test session apart from another one on the same ROS domain.
NAMESPACE = f'/ellipath_test_{os.getpid()}'

CONFIG = Path(__file__).resolve().parents[1] / 'config'
GEOMETRY = build_settings(parameter_defaults()).planner.geometry
JOINT_NAMES = ['joint_1', 'joint_2', 'joint_3']
HOME = (0.0, 0.0, -0.8)
PICK = (0.10, 0.05, -0.85)
OTHER_PICK = (0.05, 0.20, -0.86)
PLACE = (-0.15, -0.10, -0.82)


# --- conversions, no ROS graph ------------------------------------------------------------

@pytest.mark.parametrize('seconds, sec, nanosec', [
    (0.0, 0, 0), (0.004, 0, 4_000_000), (1.5, 1, 500_000_000), (2.9999999999, 3, 0),
    (123.000000001, 123, 1)])
def test_duration_splits_seconds_and_nanoseconds(seconds, sec, nanosec):
    duration = duration_from_seconds(seconds)
    assert (duration.sec, duration.nanosec) == (sec, nanosec)
    assert seconds_from_duration(duration) == pytest.approx(seconds, abs=1e-9)


def test_joint_positions_are_picked_by_name():
    state = JointState(name=['gripper', 'joint_3', 'joint_1', 'joint_2'],
                       position=[9.0, 0.3, 0.1, 0.2])
    assert joint_positions_by_name(state, JOINT_NAMES).tolist() == [0.1, 0.2, 0.3]
    assert joint_positions_by_name(JointState(name=['joint_1', 'joint_2'], position=[0.1, 0.2]),
                                   JOINT_NAMES) is None
    assert joint_positions_by_name(JointState(name=JOINT_NAMES, position=[]),
                                   JOINT_NAMES) is None
    assert joint_positions_by_name(JointState(name=JOINT_NAMES, position=[0.1, math.nan, 0.0]),
                                   JOINT_NAMES) is None


def test_key_values_format_numbers_and_text():
    values = key_values({'duration': 0.123456789012, 'count': 80, 'policy': 'paper'})
    assert [(item.key, item.value) for item in values] == [
        ('duration', '0.123456789'), ('count', '80'), ('policy', 'paper')]


def test_pairing_in_sequence_and_stamp_modes():
    pairing = PosePairing()
    first, second = Time(sec=1), Time(sec=2)
    assert pairing.add_pick(first, 'a', 'sequence', 10) is None
    assert 'replaced' in pairing.add_pick(second, 'b', 'sequence', 10)
    assert pairing.take_pick(first, 'sequence') == 'b'
    with pytest.raises(UnpairedPlaceError, match='pick_pose'):
        pairing.take_pick(first, 'sequence')
    assert pairing.add_pick(first, 'a', 'stamp', 2) is None
    assert pairing.add_pick(second, 'b', 'stamp', 2) is None
    assert 'queue full' in pairing.add_pick(Time(sec=3), 'c', 'stamp', 2)
    assert pairing.take_pick(second, 'stamp') == 'b'
    with pytest.raises(UnpairedPlaceError, match='stamp'):
        pairing.take_pick(first, 'stamp')  # dropped when the queue was full
    assert len(pairing) == 1
    pairing.add_pick(first, 'a', 'sequence', 2)  # a mode change drops what was pending
    assert len(pairing) == 1


# --- the node on a ROS graph ----------------------------------------------------------------

def pose(position, frame_id='base_link', stamp=None):
    """Return a PoseStamped at ``position`` with identity orientation."""
    message = PoseStamped()
    message.header.frame_id = frame_id
    if stamp is not None:
        message.header.stamp = stamp
    message.pose.position.x, message.pose.position.y, message.pose.position.z = position
    message.pose.orientation.w = 1.0
    return message


def tcp_positions(trajectory):
    """Return the TCP positions of the points of a JointTrajectory message."""
    return forward_kinematics(joint_trajectory_data(trajectory).positions, GEOMETRY)


def distance_to(trajectory, point):
    """Return how close the TCP passes to ``point`` as the controller interpolates [m]."""
    data = joint_trajectory_data(trajectory)
    times = np.linspace(0.0, data.duration, 4001)
    reached = forward_kinematics(quintic_interpolate(data, times)[0], GEOMETRY)
    return float(np.min(np.linalg.norm(reached - point, axis=1)))


def values_of(status):
    """Return the key/values of a DiagnosticStatus as a dict."""
    return {item.key: item.value for item in status.values}


class Harness:
    """An EllipathNode and a client node spun together by one executor."""

    def __init__(self, context, parameters=None, cli_args=None):
        overrides = [Parameter(name, value=value) for name, value in (parameters or {}).items()]
        self.node = EllipathNode(context=context, namespace=NAMESPACE,
                                 parameter_overrides=overrides, cli_args=cli_args)
        self.client = Node('ellipath_test_client', context=context, namespace=NAMESPACE)
        self.pick_publisher = self.client.create_publisher(PoseStamped, 'pick_pose', 10)
        self.place_publisher = self.client.create_publisher(PoseStamped, 'place_pose', 10)
        self.joint_state_publisher = self.client.create_publisher(JointState, 'joint_states', 10)
        self.trajectories, self.statuses, self.markers = [], [], []
        self.client.create_subscription(JointTrajectory, 'joint_trajectory',
                                        self.trajectories.append, 10)
        self.client.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                        10)
        self.client.create_subscription(MarkerArray, 'ellipath_node/path_markers',
                                        self.markers.append, 10)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.client)
        # Both ends of every topic must have matched, or a first message may be dropped.
        topics = {f'{NAMESPACE}/{name}' for name in (
            'pick_pose', 'place_pose', 'joint_states', 'joint_trajectory',
            'ellipath_node/path_markers')} | {'/diagnostics'}
        publishers = [publisher for node in (self.node, self.client)
                      for publisher in node.publishers if publisher.topic_name in topics]
        subscriptions = [subscription for node in (self.node, self.client)
                         for subscription in node.subscriptions
                         if subscription.topic_name in topics]
        assert len(publishers) == len(subscriptions) == len(topics)
        assert self.spin_until(lambda: (
            all(publisher.get_subscription_count() > 0 for publisher in publishers)
            and all(subscription.get_publisher_count() > 0 for subscription in subscriptions)))

    def _on_diagnostics(self, message):
        """Keep the statuses of this harness's node (/diagnostics is shared)."""
        hardware_id = self.node.get_fully_qualified_name()
        self.statuses.extend(status for status in message.status
                             if status.hardware_id == hardware_id)

    def close(self):
        """Destroy both nodes and the executor."""
        self.executor.shutdown()
        self.node.destroy_node()
        self.client.destroy_node()

    def spin_until(self, condition, timeout=TIMEOUT):
        """Spin until ``condition()`` holds; return whether it did within ``timeout``."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.02)
        return True

    def spin_for(self, duration):
        """Spin for ``duration`` seconds."""
        self.spin_until(lambda: False, timeout=duration)

    def send_pick(self, position, **pose_options):
        """Publish a pick and spin until the node has queued it or said something about it."""
        pending, statuses = self.node.pending_pick_count, len(self.statuses)
        self.pick_publisher.publish(pose(position, **pose_options))
        assert self.spin_until(lambda: self.node.pending_pick_count != pending
                               or len(self.statuses) > statuses)

    def send_place(self, position, **pose_options):
        """Publish a place; return the node's diagnostics status and its trajectory or None."""
        statuses, trajectories = len(self.statuses), len(self.trajectories)
        self.place_publisher.publish(pose(position, **pose_options))
        assert self.spin_until(lambda: len(self.statuses) > statuses)
        status = self.statuses[-1]
        if status.level == DiagnosticStatus.OK:
            assert self.spin_until(lambda: len(self.trajectories) > trajectories)
        self.spin_for(SETTLE)
        assert len(self.trajectories) - trajectories == (status.level == DiagnosticStatus.OK)
        return status, self.trajectories[-1] if len(self.trajectories) > trajectories else None

    def cycle(self, pick, place, **pose_options):
        """Send a pick and a place; return the status and trajectory of the place."""
        self.send_pick(pick, **pose_options)
        return self.send_place(place, **pose_options)


@pytest.fixture
def make_harness(ros_context):
    """Return a factory of harnesses, closed after the test."""
    harnesses = []

    def make(parameters=None, cli_args=None):
        harness = Harness(ros_context, parameters, cli_args)
        harnesses.append(harness)
        return harness

    yield make
    for harness in harnesses:
        harness.close()


def test_a_pair_gives_one_valid_trajectory_from_home_to_the_place(make_harness):
    harness = make_harness()
    status, trajectory = harness.cycle(PICK, PLACE)

    assert (status.level, status.message) == (DiagnosticStatus.OK, 'planned')
    assert status.name == 'ellipath_node: plan'
    assert status.hardware_id == f'{NAMESPACE}/ellipath_node'
    values = values_of(status)
    assert values['start_source'] == 'home_position'
    assert 0.0 < float(values['plan_time']) <= float(values['receive_to_publish_latency'])
    assert int(values['n_points']) == len(trajectory.points)

    assert trajectory.header.frame_id == 'base_link'
    assert (trajectory.header.stamp.sec, trajectory.header.stamp.nanosec) == (0, 0)
    assert list(trajectory.joint_names) == JOINT_NAMES
    data = joint_trajectory_data(trajectory)
    validate_jtc(data, expect_names=JOINT_NAMES)
    np.testing.assert_allclose(data.positions[0], inverse_kinematics(HOME, GEOMETRY), atol=1e-9)
    np.testing.assert_allclose(data.positions[-1], inverse_kinematics(PLACE, GEOMETRY),
                               atol=1e-9)
    assert distance_to(trajectory, PICK) < PASSES

    assert harness.markers, 'path markers are published while someone listens'
    markers = harness.markers[-1].markers
    assert markers[0].action == Marker.DELETEALL
    types = [marker.type for marker in markers[1:]]
    assert types[:2] == [Marker.LINE_STRIP, Marker.SPHERE_LIST] and Marker.SPHERE in types
    assert all(marker.header.frame_id == 'base_link' for marker in markers)


def test_the_next_cycle_starts_where_the_last_one_ended(make_harness):
    harness = make_harness({'header_stamp': 'now'})
    harness.cycle(PICK, PLACE)
    status, trajectory = harness.cycle(OTHER_PICK, PICK)
    assert values_of(status)['start_source'] == 'last_trajectory'
    np.testing.assert_allclose(tcp_positions(trajectory)[0], PLACE, atol=1e-9)
    assert trajectory.header.stamp.sec > 0, 'header_stamp now'


def test_the_cycle_starts_at_the_joint_states_while_they_are_fresh(make_harness):
    harness = make_harness({'joint_state_timeout': 1.0})
    start = np.array([0.02, -0.03, -0.78])
    q = inverse_kinematics(start, GEOMETRY)
    state = JointState(name=['joint_3', 'gripper', 'joint_1', 'joint_2'],
                       position=[q[2], 0.5, q[0], q[1]])
    harness.joint_state_publisher.publish(state)
    assert harness.spin_until(lambda: harness.node._latest_joint_state is not None)
    status, trajectory = harness.cycle(PICK, PLACE)
    assert values_of(status)['start_source'] == 'joint_states'
    np.testing.assert_allclose(trajectory.points[0].positions, q, atol=1e-9)

    time.sleep(1.1)  # the joint state is now stale
    status, trajectory = harness.cycle(OTHER_PICK, PICK)
    assert values_of(status)['start_source'] == 'last_trajectory'


@pytest.mark.parametrize('pick, place, options, reason', [
    ((math.nan, 0.0, -0.8), PLACE, {}, 'finite'),
    ((0.0, math.inf, -0.8), PLACE, {}, 'finite'),
    (PICK, (0.1, 0.0, math.nan), {}, 'finite'),
    ((5.0, 0.0, -0.8), PLACE, {}, 'reachable'),
    (PICK, (5.0, 0.0, -0.8), {}, 'reachable'),
    (PICK, PLACE, {'frame_id': 'world'}, 'frame_id'),
    (None, PLACE, {}, 'pick_pose'),
    (PICK, PICK, {}, ''),
], ids=['nan_pick', 'inf_pick', 'nan_place', 'unreachable_pick', 'unreachable_place',
        'wrong_frame', 'place_without_pick', 'pick_equals_place'])
def test_a_bad_request_publishes_nothing_and_reports_why(make_harness, pick, place, options,
                                                         reason):
    harness = make_harness()
    if pick is not None:
        harness.send_pick(pick, **options)
    status, trajectory = harness.send_place(place, **options)
    assert trajectory is None and not harness.trajectories
    errors = [status for status in harness.statuses if status.level == DiagnosticStatus.ERROR]
    assert errors and errors[-1] is status
    assert reason in errors[0].message and errors[0].message != 'planned'
    assert values_of(errors[0])['kind'] in ('invalid_input', 'unreachable', 'unpaired',
                                            'degenerate_geometry', 'limit')
    # The node keeps serving.
    status, trajectory = harness.cycle(PICK, PLACE)
    assert status.level == DiagnosticStatus.OK and trajectory is not None


def test_an_unexpected_failure_is_reported_and_the_node_keeps_serving(
        make_harness, monkeypatch):
    harness = make_harness()

    def broken_planner(*args, **kwargs):
        raise RuntimeError('planner bug')

    monkeypatch.setattr(node_module, 'plan_cycle', broken_planner)
    status, trajectory = harness.cycle(PICK, PLACE)
    assert trajectory is None
    assert status.level == DiagnosticStatus.ERROR and 'planner bug' in status.message
    monkeypatch.undo()
    status, trajectory = harness.cycle(PICK, PLACE)
    assert status.level == DiagnosticStatus.OK and trajectory is not None


def test_a_second_pick_replaces_the_first(make_harness):
    harness = make_harness()
    harness.send_pick(PICK)
    harness.send_pick(OTHER_PICK)
    assert harness.statuses[-1].level == DiagnosticStatus.WARN
    assert 'replaced' in harness.statuses[-1].message
    assert harness.node.pending_pick_count == 1
    status, trajectory = harness.send_place(PLACE)
    assert status.level == DiagnosticStatus.OK
    assert distance_to(trajectory, OTHER_PICK) < PASSES
    assert distance_to(trajectory, PICK) > 0.01


def test_stamp_pairing_pairs_equal_stamps(make_harness):
    harness = make_harness({'pairing': 'stamp'})
    first, second = Time(sec=10, nanosec=1), Time(sec=10, nanosec=2)
    harness.send_pick(PICK, stamp=first)
    harness.send_pick(OTHER_PICK, stamp=second)
    assert harness.node.pending_pick_count == 2
    status, trajectory = harness.send_place(PLACE, stamp=second)
    assert status.level == DiagnosticStatus.OK
    assert distance_to(trajectory, OTHER_PICK) < PASSES
    status, trajectory = harness.send_place(PLACE, stamp=Time(sec=11))
    assert status.level == DiagnosticStatus.ERROR and trajectory is None
    assert values_of(status)['kind'] == 'unpaired'
    status, trajectory = harness.send_place((0.1, -0.1, -0.8), stamp=first)
    assert status.level == DiagnosticStatus.OK
    assert distance_to(trajectory, PICK) < PASSES
    assert harness.node.pending_pick_count == 0


@pytest.mark.parametrize('name, value, reason', [
    ('max_speed', -1.0, 'max_speed'),
    ('arc_policy', 'x', 'arc_policy'),
    ('pairing', 'sometimes', 'pairing'),
    ('joint_min', 2.0, 'joint'),  # in its range, but above joint_max: the set is invalid
    ('max_speed', 'fast', 'type'),
    ('frame_id', 'world', 'read-only'),
])
def test_an_invalid_parameter_change_is_rejected_and_the_old_value_stays(
        make_harness, name, value, reason):
    harness = make_harness()
    old_value = harness.node.get_parameter(name).value
    old_settings = harness.node._settings
    (result,) = harness.node.set_parameters([Parameter(name, value=value)])
    assert not result.successful and re.search(reason, result.reason)
    assert harness.node.get_parameter(name).value == old_value
    assert harness.node._settings is old_settings
    status, trajectory = harness.cycle(PICK, PLACE)
    assert status.level == DiagnosticStatus.OK and trajectory is not None


def test_a_valid_parameter_change_applies(make_harness):
    harness = make_harness()
    _, fast = harness.cycle(PICK, PLACE)
    result = harness.node.set_parameters_atomically([
        Parameter('max_speed', value=0.5), Parameter('place_dwell', value=0.2)])
    assert result.successful, result.reason
    assert harness.node.get_parameter('max_speed').value == 0.5
    _, slow = harness.cycle(PICK, PLACE)
    assert (seconds_from_duration(slow.points[-1].time_from_start)
            > seconds_from_duration(fast.points[-1].time_from_start) + 0.2)


@pytest.mark.parametrize('file_name', ['ellipath.yaml', 'paper.yaml'])
def test_the_parameter_files_load_and_plan(make_harness, file_name):
    harness = make_harness(cli_args=['--ros-args', '--params-file', str(CONFIG / file_name)])
    expected = parameter_defaults()
    if file_name == 'paper.yaml':
        expected.update(arc_policy='paper', join='paper', profile='curvature', curvature_r=0.77)
    for name, value in expected.items():
        actual = harness.node.get_parameter(name).value
        assert (list(actual) if isinstance(value, list) else actual) == value, name
    status, trajectory = harness.cycle(PICK, PLACE)
    assert status.level == DiagnosticStatus.OK, status.message
    validate_jtc(joint_trajectory_data(trajectory), expect_names=JOINT_NAMES)


def test_invalid_start_up_parameters_raise(ros_context):
    with pytest.raises(EllipathError, match='joint'):
        EllipathNode(context=ros_context, parameter_overrides=[
            Parameter('joint_min', value=1.0), Parameter('joint_max', value=0.5)])


def test_a_pair_arriving_while_the_robot_moves_is_queued_after_the_running_one(make_harness):
    harness = make_harness()
    first_status, first = harness.cycle(PICK, PLACE)
    # Sent at once: the first trajectory (about 0.5 s) is still running.
    status, second = harness.cycle(OTHER_PICK, PICK)
    values = values_of(status)
    assert values['start_source'] == 'last_trajectory'
    assert values['queued_after_last_trajectory'] == 'true'
    np.testing.assert_allclose(tcp_positions(second)[0], PLACE, atol=1e-9)
    stamp = second.header.stamp.sec + 1e-9 * second.header.stamp.nanosec
    assert stamp > 0.0, 'a queued trajectory carries its start time'
    # The node expects the robot free when the second one ends: first end + second duration.
    busy_until = harness.node._busy_until.nanoseconds * 1e-9
    assert busy_until == pytest.approx(stamp + float(values['duration']), abs=1e-6)
    assert float(values_of(first_status)['duration']) > 0.0
