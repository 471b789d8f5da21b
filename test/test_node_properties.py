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
Property-based tests of ellipath_node's inputs (hypothesis, profile as test_properties.py).

One EllipathNode runs in this process with its planning and release threads. Generated
messages go straight to its intake callbacks (what the executor calls for each message):
poses with NaN, +-inf, huge, tiny and subnormal coordinates, zero, NaN and huge quaternions,
wrong or empty frames, out-of-order, duplicate and far-future stamps, places without a pick,
PoseArrays of 0 to 4 poses; between them, valid and invalid parameter changes while the
threads plan and release. What the node publishes is recorded in place of its trajectory
and /diagnostics publishers. Properties: the node keeps serving, each pair message is counted
once and gets a status, every rejection has a reason, a refused parameter change leaves the
configuration as it was, and every trajectory released is one JTC takes, within the joint
limits on its interpolation and within the safe workspace as executed. Valid pairs, sent
while parameters change, also give trajectories that end at their own places, in order. The
node has no robot here: it releases each motion as soon as it is planned (see ``node``).
"""

import itertools
import math
import os
import re
import time

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from ellipath_ros.conversions import joint_trajectory_data
from ellipath_ros.conversions import numbers_in_ranges
from ellipath_ros.core.settings import default_values
from ellipath_ros.node import EllipathNode
from ellipath_ros.node import PLACE_WAIT
from ellipath_ros.parameters import build_settings
from geometry_msgs.msg import Pose
from geometry_msgs.msg import PoseArray
from geometry_msgs.msg import PoseStamped
from hypothesis import given
from hypothesis import settings
from hypothesis import strategies as st
import pytest
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from std_srvs.srv import Trigger
from test_properties import assert_executable
from test_properties import END_TOLERANCE
from test_properties import hostile_floats
from test_properties import inside
from test_properties import SCALE
from trajectory_msgs.msg import JointTrajectory

ROS_DOMAIN_OFFSET = 6  # see conftest.py
NAMESPACE = f'/ellipath_properties_{os.getpid()}'
EXAMPLES = 1200 * SCALE  # each example sends 1 to 6 messages or parameter changes
VALID_EXAMPLES = 200 * SCALE  # each sends 1 to 5 valid pairs or parameter changes
PLAN_TIMEOUT = 30.0  # s, for an example's valid pairs to be planned and published
DRAIN_TIMEOUT = 20.0  # s, for the queue to empty at the end before it is cleared
DEFAULTS = default_values()
# The loosest configuration in force: valid parameter changes below only tighten it.
CONFIG = build_settings(DEFAULTS).planner
PAIR_IN_MESSAGE = re.compile(r'\bpair (\d+)\b')
# How far the queue's clock runs ahead of time.monotonic() [s] (see the node fixture).
ROBOT_DONE = 1e6


class Recorder:
    """Stands in for a publisher: keeps every message published."""

    def __init__(self, message_type):
        self.message_type = message_type
        self.messages = []

    def publish(self, message):
        # The node publishes its trajectories and statuses serialized.
        self.messages.append(deserialize_message(message, self.message_type)
                             if isinstance(message, bytes) else message)


@pytest.fixture(scope='module')
def node(ros_context):
    """
    Yield an EllipathNode whose trajectories and statuses are recorded, released at once.

    There is no robot: its queue's clock runs ROBOT_DONE ahead of time.monotonic(), as if
    every motion released had ended, so the release thread publishes each motion as soon as
    it is planned instead of waiting its duration (about 0.5 s) in real time, and many more
    plans reach the publisher. When to release is tested in test_node.py with Jazzy's JTC.
    """
    node = EllipathNode(context=ros_context, namespace=NAMESPACE)
    node._trajectory_publisher = Recorder(JointTrajectory)
    node._diagnostics_publisher = Recorder(DiagnosticArray)
    node.sequencer.clock = lambda: time.monotonic() + ROBOT_DONE
    yield node
    node.destroy_node()


def statuses(node):
    """Return every status the node published so far."""
    return [status for array in node._diagnostics_publisher.messages for status in array.status]


def values_of(status):
    """Return the key/values of a DiagnosticStatus as a dict."""
    return {item.key: item.value for item in status.values}


# --- generated inputs ------------------------------------------------------------------------

coordinate_triples = st.one_of(
    inside.map(tuple), inside.map(tuple), inside.map(tuple),
    st.tuples(hostile_floats, hostile_floats, hostile_floats),
    st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), hostile_floats))
quaternions = st.one_of(
    st.just((0.0, 0.0, 0.0, 1.0)),
    st.sampled_from([(0.0, 0.0, 0.0, 0.0), (math.nan,) * 4, (math.inf, 0.0, 0.0, 0.0),
                     (1e300, 1e300, 0.0, 0.0), (5e-324, 0.0, 0.0, 0.0)]),
    st.tuples(hostile_floats, hostile_floats, hostile_floats, hostile_floats))
frames = st.one_of(st.just('base_link'), st.just('base_link'), st.just('base_link'),
                   st.sampled_from(['', 'world', 'base_link ', '/base_link', 'BASE_LINK']),
                   st.text(max_size=8))
# Stamps repeat (small range), go back, and reach the far future (int32 seconds).
stamps = st.tuples(st.one_of(st.integers(0, 5), st.integers(-2**31, 2**31 - 1)),
                   st.one_of(st.just(0), st.integers(0, 999_999_999)))


def _pose(position, orientation):
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = position
    (pose.orientation.x, pose.orientation.y, pose.orientation.z,
     pose.orientation.w) = orientation
    return pose


@st.composite
def pose_messages(draw):
    """Draw (topic, message) for pick_pose, place_pose or pick_place."""
    topic = draw(st.sampled_from(['pick_pose', 'place_pose', 'pick_place']))
    frame, (sec, nanosec) = draw(frames), draw(stamps)
    if topic == 'pick_place':
        message = PoseArray()
        count = draw(st.sampled_from([2, 2, 2, 0, 1, 3]))
        message.poses = [_pose(draw(coordinate_triples), draw(quaternions))
                         for _ in range(count)]
    else:
        message = PoseStamped()
        message.pose = _pose(draw(coordinate_triples), draw(quaternions))
    message.header.frame_id = frame
    message.header.stamp.sec, message.header.stamp.nanosec = sec, nanosec
    return topic, message


# Valid changes only tighten the default limits, so CONFIG bounds every plan.
TIGHTER = {'max_speed': (1.0, 4.0), 'max_accel': (10.0, 50.0), 'max_jerk': (1000.0, 5000.0),
           'max_joint_velocity': (3.0, 10.0), 'max_joint_accel': (50.0, 200.0),
           'pick_dwell': (0.0, 0.1), 'place_dwell': (0.0, 0.1)}
# Values each of these parameters must refuse.
INVALID_VALUES = st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0.0, 1e300, 'fast',
                                  True, [1.0]])
INVALID_NAMES = ['max_speed', 'max_accel', 'max_jerk', 'max_joint_velocity',
                 'max_joint_accel', 'workspace_radius', 'knot_tolerance']
parameter_changes = st.one_of(
    st.sampled_from(sorted(TIGHTER)).flatmap(
        lambda name: st.tuples(st.just(name), st.floats(*TIGHTER[name]), st.just(True))),
    st.tuples(st.sampled_from(INVALID_NAMES), INVALID_VALUES, st.just(False)),
    st.tuples(st.just('pairing'), st.sampled_from(['stamp', 'sequence', 'random', '']),
              st.just(None)))
steps = st.lists(st.one_of(pose_messages(), pose_messages(), pose_messages(),
                           parameter_changes.map(lambda change: ('parameter', change))),
                 min_size=1, max_size=6)


# --- properties ------------------------------------------------------------------------------

def _change_parameter(node, change):
    """Set one parameter; a refused change must give a reason and change nothing."""
    name, value, valid = change
    before = node.get_parameter(name).value
    result = node.set_parameters([Parameter(name, value=value)])[0]
    if valid is True:
        assert result.successful, (name, value, result.reason)
    elif valid is False:
        assert not result.successful, (name, value)
    if result.successful:
        assert node.get_parameter(name).value == value
    else:
        assert result.reason, (name, value)
        assert node.get_parameter(name).value == before


@settings(max_examples=EXAMPLES)
@given(sequence=steps)
def test_any_input_is_counted_answered_and_leaves_the_node_serving(node, sequence):
    # A place read before its pick waits for it (PLACE_WAIT): a pair counted when it is
    # taken in (with its pick) or rejected (its wait over), not while it waits.
    received = node.sequencer.counts()['received'] + node._pairing.waiting_places
    picks_received = node._pairing.counts()['received']
    published = len(node._diagnostics_publisher.messages)
    pairs = 0
    for topic, item in sequence:
        if topic == 'parameter':
            _change_parameter(node, item)
            continue
        callback = {'pick_pose': node._on_pick, 'place_pose': node._on_place,
                    'pick_place': node._on_pick_place}[topic]
        callback(item)
        pairs += topic != 'pick_pose'
    node.publish_intake_statuses()  # as the node's timer does every STATUS_PERIOD
    counts = node.sequencer.counts()
    # Each place_pose and pick_place message is one pair, counted once.
    assert counts['received'] + node._pairing.waiting_places == received + pairs
    assert counts['received'] == sum(counts[name] for name in (
        'released', 'rejected', 'dropped', 'queued', 'releasing'))
    # Each pick_pose message is counted once too, and ends in exactly one outcome.
    picks = node._pairing.counts()
    assert picks['received'] == picks_received + sum(
        topic == 'pick_pose' for topic, _ in sequence)
    assert picks['received'] == sum(picks[name] for name in (
        'paired', 'pending', 'invalid', 'replaced', 'evicted', 'cleared'))
    assert all(worker.is_alive() for worker in node._workers)
    for array in node._diagnostics_publisher.messages[published:]:
        for status in array.status:
            if status.level != DiagnosticStatus.OK:
                kind = values_of(status).get('kind')
                assert kind not in (None, '', 'internal'), status
                # A rejection says what was expected; pick_replaced, pick_evicted and
                # pick_cleared only warn of a pick that will never be paired (its place, if
                # any, is rejected as unpaired).
                if not kind.startswith('pick_'):
                    assert ': expected ' in status.message, status.message


# Valid pairs: points of the workspace, in the robot's frame, orientations anything (ignored),
# stamps of their own; as one pick_place message or as a pick_pose and a place_pose.
valid_pairs = st.tuples(inside, inside, quaternions, st.booleans())
valid_changes = st.sampled_from(sorted(TIGHTER)).flatmap(
    lambda name: st.tuples(st.just(name), st.floats(*TIGHTER[name]), st.just(True)))
valid_steps = st.lists(st.one_of(valid_pairs.map(lambda pair: ('pair', pair)),
                                 valid_pairs.map(lambda pair: ('pair', pair)),
                                 valid_pairs.map(lambda pair: ('pair', pair)),
                                 valid_changes.map(lambda change: ('parameter', change))),
                       min_size=1, max_size=5)
# Stamps of the valid pairs: unique, and beyond those of the hostile inputs above.
valid_stamps = itertools.count(2**30)


def _idle(node):
    """Return whether the node holds no pair (waiting, planned, held, releasing, unpaired)."""
    # As the node's timer does: a place the hostile inputs left waiting for its pick expires
    # PLACE_WAIT later and is answered now, not in the middle of the next example.
    node.publish_intake_statuses()
    counts = node.sequencer.counts()
    return (counts['queued'] == 0 and counts['releasing'] == 0
            and node._pairing.waiting_places == 0)


@settings(max_examples=VALID_EXAMPLES)
@given(sequence=valid_steps)
def test_valid_pairs_under_parameter_changes_give_safe_trajectories_to_their_places(
        node, sequence):
    """
    Each valid pair is published (JTC rules, limits as executed, workspace) or rejected.

    Many plans reach the publisher here (the hostile inputs above are mostly rejected): each
    example waits until its pairs are planned and released, while parameters change. Each
    trajectory ends at the place of the next pair not rejected, in the order sent, and
    starts where the one before it ended.
    """
    assert node.set_parameters([Parameter('pairing', value='stamp')])[0].successful
    deadline = time.monotonic() + PLAN_TIMEOUT
    while not _idle(node):  # what the hostile inputs left
        assert time.monotonic() < deadline
        time.sleep(0.005)
    published = len(node._trajectory_publisher.messages)
    diagnostics = len(node._diagnostics_publisher.messages)
    first_pair = node.sequencer.counts()['received'] + 1
    places = []
    for kind, item in sequence:
        if kind == 'parameter':
            _change_parameter(node, item)
            continue
        pick, place, orientation, one_message = item
        stamp = next(valid_stamps)
        if one_message:
            message = PoseArray()
            message.poses = [_pose(pick, orientation), _pose(place, orientation)]
            message.header.frame_id, message.header.stamp.sec = 'base_link', stamp
            node._on_pick_place(message)
        else:
            for callback, position in ((node._on_pick, pick), (node._on_place, place)):
                message = PoseStamped()
                message.pose = _pose(position, orientation)
                message.header.frame_id, message.header.stamp.sec = 'base_link', stamp
                callback(message)
        places.append(place)
    numbers = set(range(first_pair, first_pair + len(places)))
    node.publish_intake_statuses()
    while True:  # until each pair has its 'released' status or its rejection
        released, rejected = set(), set()
        for array in node._diagnostics_publisher.messages[diagnostics:]:
            for status in array.status:
                if status.message == 'released':
                    released |= _pairs_named(status)
                elif status.level != DiagnosticStatus.OK:
                    kind = values_of(status).get('kind')
                    # Valid pairs: no queue_full (one example at a time), and no
                    # invalid_input (a dwell of 1e-79 s once gave two points one time).
                    assert kind not in ('queue_full', 'unpaired', 'internal',
                                        'invalid_input'), status.message
                    if not kind.startswith('pick_'):  # pick_cleared: the pairing switch
                        assert ': expected ' in status.message, status.message
                        rejected |= _pairs_named(status)
        if numbers <= released | rejected:
            break
        assert time.monotonic() < deadline, 'the valid pairs were not answered in time'
        time.sleep(0.005)
    expected = [place for number, place in enumerate(places, first_pair)
                if number not in rejected]
    trajectories = node._trajectory_publisher.messages[published:]
    assert len(trajectories) == len(expected)
    previous_end = None
    for message, place in zip(trajectories, expected):
        tcp = assert_executable(joint_trajectory_data(message), CONFIG)
        assert abs(tcp[-1] - place).max() <= END_TOLERANCE
        if previous_end is not None:
            assert abs(tcp[0] - previous_end).max() <= END_TOLERANCE
        previous_end = tcp[-1]


def _pairs_named(status):
    """Return the pair numbers a status is about."""
    values = values_of(status)
    named = {int(number) for number in values.get('dropped_pairs', '').split()}
    if 'pair' in values:
        named.add(int(values['pair']))
    named.update(numbers_in_ranges(values.get('pairs', '')))
    named.update(int(number) for number in PAIR_IN_MESSAGE.findall(status.message))
    return named


def test_every_pair_has_a_status_and_every_trajectory_is_safe(node):
    """After the generated inputs: drain (or clear) the queue, then check what came out."""
    deadline = time.monotonic() + DRAIN_TIMEOUT
    while len(node.sequencer) and time.monotonic() < deadline:
        time.sleep(0.1)
    node._on_clear_queue(Trigger.Request(), Trigger.Response())
    time.sleep(max(0.5, PLACE_WAIT))  # a release in progress at the clear publishes its status
    node._expire_places()  # the places still waiting for a pick: rejected, with a status
    assert node._pairing.waiting_places == 0
    counts = node.sequencer.counts()
    assert counts['received'] > 1000
    # Most from the valid pairs (13 in all when the hostile inputs were the only ones).
    assert counts['released'] >= VALID_EXAMPLES // 2
    named = set()
    for status in statuses(node):
        named |= _pairs_named(status)
    assert set(range(1, counts['received'] + 1)) <= named
    for message in node._trajectory_publisher.messages:
        assert_executable(joint_trajectory_data(message), CONFIG)
