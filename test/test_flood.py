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
A short flood (scripts/flood.py, 3 s at 300 pairs/s) against the node in another process.

The long flood (60 s at 1000 pairs/s) is a script, see docs/reliability.md. No timing is
asserted here; the latencies are only reported by the script.
"""

import os
import sys

import numpy as np
import pytest
from rclpy.impl.implementation_singleton import rclpy_implementation

ROS_DOMAIN_OFFSET = 5  # see conftest.py

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(__file__)), 'scripts'))
import flood  # noqa: E402, I100 (scripts/ is not a package)


def test_pair_ids_survive_the_position_encoding():
    """Every id decodes back from its place, and neighbouring picks are far apart."""
    ids = np.arange(0, 61_000, 7)
    assert all(flood.pair_of_place(flood.place_of(pair_id)) == pair_id for pair_id in ids)
    assert np.linalg.norm(flood.pick_of(1) - flood.pick_of(0)) > 50 * flood.PICK_TOLERANCE


class RefusingPublisher:
    """A publisher whose DDS history is full: publish() raises as rclpy's does."""

    def __init__(self, refuse):
        self.refuse = refuse
        self.published = []

    def publish(self, message):
        if self.refuse:
            raise rclpy_implementation.RCLError('cannot publish data')
        self.published.append(message)


def sender(pick_place=False, pick=False, place=False):
    """Return a flood Recorder without ROS whose publishers refuse as asked."""
    recorder = object.__new__(flood.Recorder)
    recorder.pick_place = RefusingPublisher(pick_place)
    recorder.pick_pose = RefusingPublisher(pick)
    recorder.place_pose = RefusingPublisher(place)
    return recorder


def test_a_refused_publish_is_counted_as_refused_and_its_pair_not_sent_on():
    assert sender(pick_place=True).send(0, 1, 'pick_place') == ('pick_place', 'refused')
    assert sender().send(0, 1, 'pick_place') == ('pick_place', 'sent')
    refused_pick = sender(pick=True)
    assert refused_pick.send(1, 1, 'two_topic') == ('two_topic', 'refused')
    assert refused_pick.place_pose.published == [], 'no place for a pick that was refused'
    refused_place = sender(place=True)
    assert refused_place.send(1, 1, 'two_topic') == ('two_topic', 'place_refused')
    assert len(refused_place.pick_pose.published) == 1
    ledger = flood.sender_ledger({0: ('pick_place', 'refused'), 1: ('two_topic', 'refused'),
                                  2: ('two_topic', 'place_refused'), 3: ('two_topic', 'sent'),
                                  4: ('pick_place', 'sent')})
    assert ledger == {'pairs_attempted': 5, 'pairs_sent': 2, 'pairs_refused': 3,
                      'picks_attempted': 3, 'picks_sent': 2, 'picks_refused': 1}


def test_the_node_ledger_adds_up_only_when_every_message_has_one_outcome():
    values = {'pairs_received': '7', 'pairs_released': '2', 'pairs_rejected': '4',
              'pairs_rejected_unpaired': '1', 'pairs_rejected_queue_full': '3',
              'pairs_dropped': '1', 'pairs_dropped_cleared': '1', 'pairs_queued': '0',
              'pairs_releasing': '0', 'picks_received': '3', 'picks_paired': '1',
              'picks_pending': '1', 'picks_evicted': '1', 'queue_length': '0'}
    counts, pairs_add_up, picks_add_up = flood.node_ledger(values)
    assert counts['pairs_rejected_queue_full'] == 3 and 'queue_length' not in counts
    assert pairs_add_up and picks_add_up
    assert not flood.node_ledger({**values, 'pairs_received': '8'})[1]
    assert not flood.node_ledger({**values, 'pairs_rejected_unpaired': '2'})[1]
    assert not flood.node_ledger({**values, 'picks_received': '4'})[2]


@pytest.fixture(scope='module')
def report(ros_domain_id, tmp_path_factory, monkeypatch_module):
    """Run the short flood once for the module's tests."""
    monkeypatch_module.setenv('ROS_DOMAIN_ID', str(ros_domain_id))
    return flood.run(rate=300.0, seconds=3.0, seed=3, drain_timeout=40.0,
                     log_dir=str(tmp_path_factory.mktemp('flood')))


def test_node_survives_and_answers_a_valid_pair(report):
    assert report['alive_after'], report['node_log']
    assert report['answer_after_flood_s'] is not None
    assert report['exit_code'] == 0


def test_no_place_is_paired_with_another_pick(report):
    assert report['trajectory_pairs'] > 0
    assert report['mispaired'] == 0, report['mispaired_first']
    assert report['invalid_trajectories'] == 0
    assert report['duplicate_trajectories'] == 0


def test_every_message_sent_is_refused_or_received_and_accounted_for(report):
    sender, node = report['sender'], report['node']
    assert report['drained']
    assert report['pairs_lost_in_transport'] == 0 and report['picks_lost_in_transport'] == 0
    assert node['pairs_received'] == sender['pairs_sent']
    assert node['picks_received'] == sender['picks_sent']
    assert sender['pairs_sent'] + sender['pairs_refused'] == sender['pairs_attempted']
    assert report['pairs_add_up'] and report['picks_add_up'], node
    assert report['pairs_without_status'] == 0, report['pairs_without_status_first']
    # Overloaded: the queue was full and said so, and never grew past its depth.
    assert node.get('pairs_rejected_queue_full', 0) > 0
    assert report['max_queue_length'] <= 10


def test_only_the_invalid_pairs_are_rejected_as_invalid_or_unpaired(report):
    """A valid pair is never rejected as invalid or unpaired; each invalid one is."""
    rejections = report['invalid_rejections']
    assert rejections['invalid_input']['sent'] > 0
    for kind, count in rejections.items():
        assert count['rejected'] == count['sent'], (kind, count)


def test_expected_rejections_follow_the_stream_and_the_defect():
    sent = {0: ('pick_place', 'sent'), 1: ('two_topic', 'sent'), 2: ('two_topic', 'sent'),
            3: ('pick_place', 'refused'), 4: ('two_topic', 'place_refused'),
            5: ('two_topic', 'sent')}
    invalid = {0: 'frame', 1: 'frame', 2: 'nan', 3: 'nan', 4: 'frame'}
    assert flood.expected_rejections(sent, invalid) == {'invalid_input': 3, 'unpaired': 0}
