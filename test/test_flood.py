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

ROS_DOMAIN_OFFSET = 5  # see conftest.py

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(__file__)), 'scripts'))
import flood  # noqa: E402, I100 (scripts/ is not a package)


def test_pair_ids_survive_the_position_encoding():
    """Every id decodes back from its place, and neighbouring picks are far apart."""
    ids = np.arange(0, 61_000, 7)
    assert all(flood.pair_of_place(flood.place_of(pair_id)) == pair_id for pair_id in ids)
    assert np.linalg.norm(flood.pick_of(1) - flood.pick_of(0)) > 50 * flood.PICK_TOLERANCE


@pytest.fixture(scope='module')
def report(ros_domain_id, tmp_path_factory, monkeypatch_module):
    """Run the short flood once for the module's tests."""
    monkeypatch_module.setenv('ROS_DOMAIN_ID', str(ros_domain_id))
    return flood.run(rate=300.0, seconds=3.0, seed=3, drain_timeout=40.0,
                     log_dir=str(tmp_path_factory.mktemp('flood')))


@pytest.fixture(scope='module')
def monkeypatch_module():
    """Yield a monkeypatch that lasts for the module."""
    with pytest.MonkeyPatch.context() as patch:
        yield patch


def test_node_survives_and_answers_a_valid_pair(report):
    assert report['alive_after'], report['node_log']
    assert report['answer_after_flood_s'] is not None
    assert report['exit_code'] == 0


def test_no_place_is_paired_with_another_pick(report):
    assert report['trajectory_pairs'] > 0
    assert report['mispaired'] == 0, report['mispaired_first']
    assert report['invalid_trajectories'] == 0
    assert report['duplicate_trajectories'] == 0


def test_every_pair_is_accounted_for(report):
    counts = report['node_counts']
    assert report['lost_before_node'] == 0
    assert counts['received'] == report['pairs_sent']
    assert report['accounting_adds_up'], counts
    assert report['pairs_without_status'] == 0, report['pairs_without_status_first']
    # Overloaded: the queue was full and said so, and never grew past its depth.
    assert report['status_kinds'].get('queue_full', 0) > 0
    assert report['max_queue_length'] <= 10
