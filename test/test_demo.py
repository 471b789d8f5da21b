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

Jazzy's joint_trajectory_controller replaces a running trajectory at its next cycle, so the
node holds each trajectory until the previous one has ended;
``test_the_burst_demo_executes_every_trajectory_after_the_one_before`` checks on the executed
motion (the controller emulated) that the burst run passes.
"""

import argparse
import re
import time

from ellipath_ros import demo
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.kinematics import reachable
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.settings import default_values
from ellipath_ros.core.workspace import SafeWorkspace
from ellipath_ros.parameters import build_settings
import numpy as np
import pytest

ROS_DOMAIN_OFFSET = 37  # see conftest.py
CYCLES = 4  # pair 3 is unreachable, pair 4's pick is behind the conveyor's frame
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
    pairs, expected = demo.cell_pairs(12)
    assert len(pairs) == 12 and expected == {6: 'unreachable', 9: 'workspace'}
    picks = np.array([pick for pick, _ in pairs])
    places = np.array([place for _, place in pairs])
    good = ~np.isin(np.arange(12), list(expected))
    assert reachable(picks, CONFIG.geometry).all()
    assert reachable(places[np.arange(12) != 6], CONFIG.geometry).all()
    assert not reachable(places[6], CONFIG.geometry)
    points = np.vstack((picks[good], places[good]))
    assert (np.hypot(points[:, 0], points[:, 1]) <= 0.35).all()
    assert ((points[:, 2] >= -1.0) & (points[:, 2] <= -0.6)).all()
    assert set(picks[good, 2]) == {-0.85} and set(places[good, 2]) == {-0.80, -0.83}
    distance = np.linalg.norm(places[good, :2] - picks[good, :2], axis=1)
    assert ((distance > 0.25) & (distance < 0.4)).all()
    assert np.diff(picks[:5, 1]).min() > 0.0  # the conveyor advances
    # Fewer pairs: the pick behind the frame needs a pair after the unreachable one.
    assert demo.cell_pairs(4)[1] == {2: 'unreachable', 3: 'workspace'}
    assert demo.cell_pairs(2)[1] == {1: 'unreachable'}


def test_the_cell_plans_around_the_conveyor_frame_and_rejects_the_pair_behind_it():
    # The node's settings of the demo: its defaults and the cell's keep-out box.
    settings = build_settings({**default_values(),
                               'keep_out_boxes': list(demo.CELL_KEEP_OUT_BOXES)})
    assert settings.planner.workspace.keep_out_boxes == (demo.CELL_KEEP_OUT_BOXES,)
    box = np.array(demo.CELL_KEEP_OUT_BOXES)
    clearance = 0.02  # m
    near_the_frame = SafeWorkspace(keep_out_boxes=np.concatenate(
        (box[:3] - clearance, box[3:] + clearance)))
    pairs, expected = demo.cell_pairs(12)
    start, kinds = settings.home_position, {}
    for index, (pick, place) in enumerate(pairs):
        try:
            plan = plan_cycle(start, pick, place, settings.planner,
                              pick_dwell=settings.pick_dwell, place_dwell=settings.place_dwell)
        except EllipathError as error:
            kinds[index] = error.kind
            if error.kind == 'workspace':
                # The first offending point and its time, inside the frame.
                assert re.search(r'\[\d+\] at t = \d+\.\d+ s', str(error))
                assert 'inside keep_out_boxes[0]' in str(error)
            continue
        # A good pair's planned path keeps clear of the frame (well beyond the tolerance).
        for leg in plan.legs:
            path = leg.path.at_lengths(np.linspace(0.0, leg.path.length, 400)).position
            assert near_the_frame.contains(path).all()
        start = plan.end_position
    assert kinds == expected


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
    # Rejected by the node's safe workspace, naming the first point inside the frame and when.
    assert 'REJECTED (expected)' in rows[4] and 'inside keep_out_boxes[0]' in rows[4]
    assert re.search(r'\[\d+\] at t = \d+\.\d+ s', rows[4])
    for number in (1, 2):
        assert rows[number].rstrip().endswith('OK'), rows[number]
    assert '2 executed as planned, 2 rejected as expected, 0 rejected unexpectedly, ' \
        '0 invalid published, 0 not executed as planned' in output
    assert 'picks and places visited in order: 4 of 4' in output
    # The scene is the node's: its cylinder, z range and the cell's keep-out box.
    assert "safe workspace (the node's parameters): radius 400 mm" in output
    assert 'keep-out box 0 from (-260,-300,-1000) to (-210,300,-840) mm' in output
    assert 'executed TCP inside it throughout' in output
    assert '0 replaced while running' in output
    assert 'picks/min' in output and 'result: PASS' in output


def test_the_burst_demo_executes_every_trajectory_after_the_one_before(
        ros_domain_id, capsys, tmp_path):
    # A second at the pick makes every trajectory last 1.5 s, longer than any plan takes
    # here, so the next one always arrives while it runs.
    params = tmp_path / 'dwell.yaml'
    params.write_text('/**:\n  ros__parameters:\n    pick_dwell: 1.0\n')
    status, output, rows = run(capsys, '--domain-id', str(ros_domain_id), '--params-file',
                               str(params))
    assert 'burst' in output and sorted(rows) == [1, 2, 3, 4]
    assert 'REJECTED (expected)' in rows[3] and 'REJECTED (expected)' in rows[4]
    # The node holds each trajectory until the previous one has ended (Jazzy's JTC would
    # replace a running one): the executed motion follows the plan.
    assert status == 0, output
    assert '0 replaced while running' in output
    assert '0 not executed as planned' in output and 'result: PASS' in output
