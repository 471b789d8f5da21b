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
``ellipath demo``: options, the cell's pairs, and short runs over ROS.

The runs happen in this process on a domain of their own (conftest.py: 46 + 37 = 83 by
default), with DDS on this host; every wait of the demo is bounded by ``--timeout``. The
report itself is tested on synthetic runs in test_demo_report.py.

The node on main publishes a pair that arrives while a trajectory runs at once, stamped to
start when the running one ends; Jazzy's joint_trajectory_controller replaces the running
trajectory instead. So today the burst run fails on the executed motion, and
``test_the_burst_demo_detects_the_replaced_trajectories`` asserts that it does; once the node
holds each trajectory until the previous one has ended it must pass (exit 0), and that test
flips to assert so.
"""

import argparse
import re
import time

from ellipath_ros import demo
from ellipath_ros.core.kinematics import reachable
from ellipath_ros.core.planner import PlannerConfig
import numpy as np
import pytest

ROS_DOMAIN_OFFSET = 37  # see conftest.py
CYCLES = 4  # pair 3 is the bad one
TIMEOUT = 5.0  # s, each wait of the demo: discovery, pick taken, answer, next trajectory
RUN_BOUND = 60.0  # s, the whole run

CONFIG = PlannerConfig()


def parse(*argv):
    """Parse demo options the way ``ellipath demo`` does."""
    parser = argparse.ArgumentParser()
    demo.add_arguments(parser)
    return parser.parse_args(argv)


def test_options_and_their_defaults():
    args = parse()
    assert (args.cycles, args.pacing, args.profile, args.params_file, args.timeout,
            args.domain_id) == (demo.DEFAULT_CYCLES, 'burst', None, None,
                                demo.DEFAULT_TIMEOUT, None)
    args = parse('--cycles', '3', '--pacing', 'idle', '--profile', 'curvature', '--timeout',
                 '2.5', '--domain-id', '83')
    assert (args.cycles, args.pacing, args.profile, args.timeout, args.domain_id) == (
        3, 'idle', 'curvature', 2.5, 83)
    for wrong in (['--cycles', '0'], ['--timeout', 'nan'], ['--domain-id', '300'],
                  ['--profile', 'fast'], ['--pacing', 'slow']):
        with pytest.raises(SystemExit):
            parse(*wrong)


def test_the_cell_is_reachable_except_the_bad_place():
    pairs, bad = demo.cell_pairs(12)
    assert len(pairs) == 12 and bad == 6
    picks = np.array([pick for pick, _ in pairs])
    places = np.array([place for _, place in pairs])
    good = np.arange(12) != bad
    assert reachable(picks, CONFIG.geometry).all()
    assert reachable(places[good], CONFIG.geometry).all()
    assert not reachable(places[bad], CONFIG.geometry)
    points = np.vstack((picks, places[good]))
    assert (np.hypot(points[:, 0], points[:, 1]) <= 0.35).all()
    assert ((points[:, 2] >= -1.0) & (points[:, 2] <= -0.6)).all()
    assert set(picks[:, 2]) == {-0.85} and set(places[good, 2]) == {-0.80, -0.83}
    distance = np.linalg.norm(places[good, :2] - picks[good, :2], axis=1)
    assert ((distance > 0.25) & (distance < 0.4)).all()
    assert np.diff(picks[:5, 1]).min() > 0.0  # the conveyor advances


def test_a_missing_params_file_is_refused(tmp_path, capsys):
    assert demo.run_demo(parse('--params-file', str(tmp_path / 'none.yaml'))) == 2
    assert 'params-file' in capsys.readouterr().err


def run(capsys, *options):
    """Run the demo with ``options``; return (exit status, output, rows by pair number)."""
    started = time.monotonic()
    status = demo.run_demo(parse('--cycles', str(CYCLES), '--timeout', str(TIMEOUT),
                                 *options))
    assert time.monotonic() - started < RUN_BOUND
    output = capsys.readouterr().out
    rows = {int(line.split()[0]): line for line in output.splitlines()
            if line.split() and line.split()[0].isdigit()}
    return status, output, rows


def test_the_idle_paced_demo_executes_the_good_pairs_and_rejects_the_bad_one(
        ros_domain_id, capsys):
    status, output, rows = run(capsys, '--pacing', 'idle', '--domain-id', str(ros_domain_id))
    assert status == 0, output
    assert f'ROS domain {ros_domain_id}' in output
    assert sorted(rows) == [1, 2, 3, 4]
    assert 'REJECTED (expected)' in rows[3] and '900' in rows[3]
    for number in (1, 2, 4):
        assert rows[number].rstrip().endswith('OK'), rows[number]
    assert '3 executed as planned, 1 rejected as expected, 0 rejected unexpectedly, ' \
        '0 invalid published, 0 not executed as planned' in output
    assert 'picks and places visited in order: 6 of 6' in output
    assert '0 replaced while running' in output
    assert 'picks/min' in output and 'result: PASS' in output


def test_the_burst_demo_detects_the_replaced_trajectories(ros_domain_id, capsys, tmp_path):
    # A second at the pick makes every trajectory last 1.5 s, longer than any plan takes
    # here, so the next one always arrives while it runs.
    params = tmp_path / 'dwell.yaml'
    params.write_text('/**:\n  ros__parameters:\n    pick_dwell: 1.0\n')
    status, output, rows = run(capsys, '--domain-id', str(ros_domain_id), '--params-file',
                               str(params))
    assert 'burst' in output and sorted(rows) == [1, 2, 3, 4]
    assert 'REJECTED (expected)' in rows[3]
    # The node on main publishes at once with a future stamp: JTC (Jazzy) replaces the
    # running trajectory, and the executed motion shows it. To flip when the node holds
    # each trajectory until the previous one has ended: status 0 and 'result: PASS'.
    assert status == 1, output
    deviation = re.search(r'failed: executed TCP leaves the planned paths by ([0-9.]+) mm',
                          output)
    assert deviation is not None, output
    assert float(deviation.group(1)) > 0.1
    assert 'replaced while running' in deviation.group(0) + output
    assert 'NOT EXECUTED AS PLANNED' in rows[1] and 'result: FAIL' in output
