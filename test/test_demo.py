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
``ellipath demo``: the cell's pairs, the trajectory checks, and a short run over ROS.

The run happens in this process on a domain of its own (conftest.py: 46 + 37 = 83 by
default), with DDS on this host; every wait of the demo is bounded by ``--timeout``.
"""

import argparse
from dataclasses import replace
import time

from ellipath_ros import demo
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.kinematics import JointLimits
from ellipath_ros.core.kinematics import reachable
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import PlannerConfig
import numpy as np
import pytest

ROS_DOMAIN_OFFSET = 37  # see conftest.py
CYCLES = 4  # pair 3 is the bad one
TIMEOUT = 5.0  # s, each wait of the demo: discovery, pick taken, answer
RUN_BOUND = 60.0  # s, the whole run

CONFIG = PlannerConfig()
HOME = np.array([0.0, 0.0, -0.8])


def parse(*argv):
    """Parse demo options the way ``ellipath demo`` does."""
    parser = argparse.ArgumentParser()
    demo.add_arguments(parser)
    return parser.parse_args(argv)


def test_options_and_their_defaults():
    args = parse()
    assert (args.cycles, args.profile, args.params_file, args.timeout, args.domain_id) == (
        demo.DEFAULT_CYCLES, None, None, demo.DEFAULT_TIMEOUT, None)
    args = parse('--cycles', '3', '--profile', 'curvature', '--timeout', '2.5',
                 '--domain-id', '83')
    assert (args.cycles, args.profile, args.timeout, args.domain_id) == (
        3, 'curvature', 2.5, 83)
    for wrong in (['--cycles', '0'], ['--timeout', 'nan'], ['--domain-id', '300'],
                  ['--profile', 'fast']):
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


@pytest.fixture(scope='module')
def cycle():
    """Return (start, pick, place, trajectory) of a cycle planned by the core."""
    pick, place = np.array([-0.15, -0.2, -0.85]), np.array([0.14, -0.08, -0.80])
    return HOME, pick, place, plan_cycle(HOME, pick, place, CONFIG).joint_trajectory


def test_a_planned_cycle_passes_every_check(cycle):
    start, pick, place, trajectory = cycle
    check = demo.check_trajectory(trajectory, start, pick, place, CONFIG)
    assert check.problems == ()
    assert np.allclose(check.end_position, place, atol=1e-9)
    assert check.duration == pytest.approx(trajectory.duration)
    assert 0.0 < check.peak_joint_velocity <= CONFIG.joint_limits.max_velocity
    assert 0.0 < check.peak_joint_accel <= CONFIG.joint_limits.max_acceleration
    assert 0.0 < check.peak_tcp_speed <= CONFIG.limits.max_speed * 1.01


def test_the_checks_name_what_is_wrong(cycle):
    start, pick, place, trajectory = cycle

    def problems(traj=trajectory, begin=start, at=pick, to=place, config=CONFIG):
        return ' | '.join(demo.check_trajectory(traj, begin, at, to, config).problems)

    assert 'not where the robot is' in problems(begin=start + [0.01, 0.0, 0.0])
    assert 'from the pick' in problems(at=pick + [0.01, 0.0, 0.0])  # off the vertical
    assert 'not at the place' in problems(to=place + [0.0, 0.01, 0.0])
    slow = replace(CONFIG, joint_limits=JointLimits(max_velocity=1.0, max_acceleration=20.0))
    assert 'velocity' in problems(config=slow) and 'acceleration' in problems(config=slow)
    assert 'validate_jtc' in problems(config=replace(CONFIG, joint_names=('a', 'b', 'c')))
    moving = trajectory.velocities.copy()
    moving[-1] = 0.1
    assert 'validate_jtc' in problems(traj=JointTrajectoryData(
        trajectory.joint_names, trajectory.time_from_start, trajectory.positions, moving,
        trajectory.accelerations))
    rushed = JointTrajectoryData(trajectory.joint_names, trajectory.time_from_start * 0.5,
                                 trajectory.positions, trajectory.velocities * 2.0,
                                 trajectory.accelerations * 4.0)
    assert 'breaks' in problems(traj=rushed)


def test_verdicts_of_a_cycle(cycle):
    start, pick, place, trajectory = cycle
    planned = [('OK', 'planned', {'plan_time': '0.05'})]
    unreachable = [('ERROR', 'out of reach', {'topic': 'place_pose', 'kind': 'unreachable'})]

    def judge(trajectories, statuses, bad=False):
        result = demo.CycleResult(0, pick, place, bad)
        demo.evaluate_cycle(result, [(data, ()) for data in trajectories], statuses, start,
                            CONFIG)
        return result

    result = judge([trajectory], planned)
    assert (result.verdict, result.invalid_published) == ('ok', 0)
    assert result.number('plan_time') == 0.05 and np.isnan(result.number('duration'))
    assert judge([], unreachable, bad=True).verdict == 'rejected_expected'
    assert judge([], unreachable).verdict == 'rejected_unexpected'
    limit = [('ERROR', 'too fast', {'topic': 'place_pose', 'kind': 'limit'})]
    assert judge([], limit, bad=True).verdict == 'rejected_unexpected'
    assert judge([trajectory], planned, bad=True).verdict == 'not_rejected'
    result = judge([trajectory], unreachable, bad=True)
    assert (result.verdict, result.invalid_published) == ('invalid', 1)
    result = judge([trajectory, trajectory], planned)
    assert (result.verdict, result.invalid_published) == ('invalid', 1)
    assert 'INVALID: 2 trajectories for one pair' in demo.table_row(result)


def test_a_missing_params_file_is_refused(tmp_path, capsys):
    assert demo.run_demo(parse('--params-file', str(tmp_path / 'none.yaml'))) == 2
    assert 'params-file' in capsys.readouterr().err


def test_the_demo_plans_the_good_pairs_and_rejects_the_bad_one(ros_domain_id, capsys):
    started = time.monotonic()
    status = demo.run_demo(parse('--cycles', str(CYCLES), '--timeout', str(TIMEOUT),
                                 '--domain-id', str(ros_domain_id)))
    elapsed = time.monotonic() - started
    output = capsys.readouterr().out
    assert status == 0, output
    assert elapsed < RUN_BOUND
    assert f'ROS domain {ros_domain_id}' in output
    rows = {int(line.split()[0]): line for line in output.splitlines()
            if line.split() and line.split()[0].isdigit()}
    assert sorted(rows) == [1, 2, 3, 4]
    assert 'REJECTED (expected)' in rows[3] and '900' in rows[3]
    for number in (1, 2, 4):
        assert rows[number].rstrip().endswith('OK'), rows[number]
    assert '3 planned, 3 valid, 1 rejected as expected, 0 rejected unexpectedly, ' \
        '0 invalid published' in output
    assert 'picks/min' in output and 'result: PASS' in output
