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
The demo's report, judged on synthetic runs (no ROS).

Three cycles planned by the core, chained from home, with the deliberately bad pair between
the second and the third, are "received" in two ways: released one after another as each
trajectory ends with stamp zero (what the node must do), and published at once with stamps
in the future (what the node on main does, which Jazzy's JTC executes by replacing the
running trajectory).
"""

from dataclasses import replace
import math
import re

from ellipath_ros import demo_report
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.kinematics import JointLimits
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.workspace import SafeWorkspace
from ellipath_ros.demo_report import evaluate_run
from ellipath_ros.demo_report import format_report
from ellipath_ros.demo_report import PairOutcome
from ellipath_ros.demo_report import ReceivedTrajectory
import numpy as np
import pytest

CONFIG = PlannerConfig()
HOME = np.array([0.0, 0.0, -0.8])
PAIRS = (((-0.15, -0.20, -0.85), (0.14, -0.08, -0.80)),
         ((-0.15, -0.165, -0.85), (0.14, 0.0, -0.80)),
         ((-0.15, -0.13, -0.85), (0.90, 0.0, -0.80)),  # the bad one
         ((-0.15, -0.095, -0.85), (0.18, 0.0, -0.83)))
BAD = 2
T0 = 1000.0  # s, when the first pair is sent
HAND_OVER = 0.0015  # s, end of one trajectory to the arrival of the next
PERIOD = demo_report.CONTROL_PERIOD


@pytest.fixture(scope='module')
def plans():
    """Return the plans of the good pairs, each from where the one before ends."""
    result, start = [], HOME
    for index, (pick, place) in enumerate(PAIRS):
        if index != BAD:
            result.append(plan_cycle(start, pick, place, CONFIG))
            start = result[-1].end_position
    return result


def outcomes(plans, bad_answer=('ERROR', {'kind': 'unreachable', 'topic': 'place_pose'})):
    """Return the pairs as sent, answered like the node: OK with its metrics, or an error."""
    result, planned = [], iter(plans)
    for index, (pick, place) in enumerate(PAIRS):
        outcome = PairOutcome(index, np.array(pick), np.array(place),
                              'unreachable' if index == BAD else None,
                              sent_time=T0 + 0.1 * index, round_trip=0.05)
        if index == BAD:
            outcome.level, outcome.values = bad_answer
            outcome.message = 'out of reach'
        else:
            plan = next(planned)
            outcome.level, outcome.message = 'OK', 'planned'
            outcome.values = {key: str(value) for key, value in plan.metrics.items()}
        result.append(outcome)
    return result


def next_cycle(time):
    """Return the first control cycle at or after ``time`` (cycles at T0 + k PERIOD)."""
    return T0 + math.ceil(round((time - T0) / PERIOD, 6)) * PERIOD


def released_in_sequence(plans, hand_over=HAND_OVER):
    """Each trajectory arrives ``hand_over`` after the previous one ends, stamp zero."""
    received, arrival = [], T0
    for plan in plans:
        trajectory = plan.joint_trajectory
        received.append(ReceivedTrajectory(trajectory, 0.0, arrival))
        arrival = next_cycle(arrival) + trajectory.duration + hand_over
    return received


def published_at_once(plans, spacing=0.1):
    """Each trajectory arrives ``spacing`` after the one before, stamped to start at its end."""
    received, end = [], None
    for number, plan in enumerate(plans):
        arrival = T0 + spacing * number
        stamp = 0.0 if end is None else end
        received.append(ReceivedTrajectory(plan.joint_trajectory, stamp, arrival))
        end = (next_cycle(arrival) if end is None else end) + plan.joint_trajectory.duration
    return received


def test_trajectories_released_one_after_another_pass(plans):
    report = evaluate_run(outcomes(plans), released_in_sequence(plans), HOME, CONFIG, T0)
    assert report.passed, report.failures
    assert [row.verdict for row in report.rows] == ['ok', 'ok', 'rejected_expected', 'ok']
    figures = report.figures
    assert figures['executed_deviation_max'] < 0.05 * demo_report.PATH_TOLERANCE
    assert (figures['executed_visits'], figures['visit_targets']) == (6, 6)
    assert figures['executed_replacements'] == 0
    # Each arrival is taken up at the next 1 ms cycle: the gap is 1.5 to 2.5 ms.
    assert HAND_OVER <= figures['executed_gap_p50'] <= figures['executed_gap_max']
    assert figures['executed_gap_max'] <= HAND_OVER + PERIOD + 1e-9
    durations = [plan.joint_trajectory.duration for plan in plans]
    span = sum(durations) + 2 * figures['executed_gap_p50']
    assert figures['executed_span'] == pytest.approx(span, abs=2 * PERIOD)
    assert figures['executed_picks_per_min'] == pytest.approx(60.0 * 3 / span, rel=2e-3)
    assert figures['planned_picks_per_min'] == pytest.approx(60.0 * 3 / sum(durations))
    assert figures['executed_peak_joint_velocity'] <= CONFIG.joint_limits.max_velocity
    text = format_report(report, CONFIG)
    assert 'result: PASS' in text and 'failed:' not in text
    assert 'picks/min' in text and 'REJECTED (expected)' in text


def test_trajectories_published_at_once_fail_on_the_executed_deviation(plans):
    report = evaluate_run(outcomes(plans), published_at_once(plans), HOME, CONFIG, T0)
    assert not report.passed
    figures = report.figures
    assert figures['executed_replacements'] == 2
    assert figures['executed_deviation_max'] > 0.01  # centimetres, not micrometres
    assert figures['executed_visits'] < 6
    deviation = [failure for failure in report.failures
                 if failure.startswith('executed TCP leaves the planned paths by')]
    assert len(deviation) == 1 and 'replaced while running' in deviation[0]
    reported = float(re.search(r'by ([0-9.]+) mm', deviation[0]).group(1))
    assert reported == pytest.approx(figures['executed_deviation_max'] * 1e3, abs=0.01)
    verdicts = [row.verdict for row in report.rows]
    assert verdicts[BAD] == 'rejected_expected'
    assert verdicts.count('not_executed') == 3
    assert 'replaced by the next trajectory' in report.rows[0].reason
    assert report.rows[1].gap < 0.0
    assert 'result: FAIL' in format_report(report, CONFIG)


def test_a_hand_over_just_before_the_end_is_judged_by_the_path(plans):
    # Two cycles early the robot is micrometres from the place, nearly at rest: the
    # replacement is reported, but the path and the visits are intact.
    report = evaluate_run(outcomes(plans), released_in_sequence(plans, hand_over=-0.002),
                          HOME, CONFIG, T0)
    assert report.passed, report.failures
    assert report.figures['executed_replacements'] == 2
    assert report.figures['executed_gap_max'] < 0.0
    assert 'took over while the previous trajectory ran' in report.rows[1].reason
    assert report.rows[1].verdict == 'ok'


def test_the_executed_tcp_is_judged_by_the_nodes_safe_workspace(plans):
    # The same executed motion, judged against a workspace with a box across the first
    # pair's path (a box the planner did not know of): the first sample inside it fails the
    # run, named with its time; the report describes the workspace it judged against.
    pick, place = np.array(PAIRS[0][0]), np.array(PAIRS[0][1])
    middle = (pick + place) / 2.0
    box = (*(middle - [0.01, 0.3, 0.3]), *(middle + [0.01, 0.3, 0.3]))
    boxed = replace(CONFIG, workspace=SafeWorkspace(keep_out_boxes=box))
    report = evaluate_run(outcomes(plans), released_in_sequence(plans), HOME, boxed, T0)
    assert not report.passed and report.figures['executed_workspace_clear'] is False
    [failure] = [failure for failure in report.failures
                 if failure.startswith('executed TCP[')]
    assert re.search(r'^executed TCP\[\d+\] at t = \d+\.\d+ s: ', failure)
    assert 'inside keep_out_boxes[0]' in failure
    text = format_report(report, boxed)
    assert 'keep-out box 0 from' in text and 'executed TCP NOT inside it' in text
    # Without the box: inside throughout.
    report = evaluate_run(outcomes(plans), released_in_sequence(plans), HOME, CONFIG, T0)
    assert report.figures['executed_workspace_clear'] is True
    assert 'executed TCP inside it throughout' in format_report(report, CONFIG)


def test_a_planned_bad_pair_and_an_unexpected_rejection_fail(plans):
    report = evaluate_run(outcomes(plans, ('OK', {})), released_in_sequence(plans), HOME,
                          CONFIG, T0)
    assert report.rows[BAD].verdict == 'not_rejected'
    # Its trajectory is the bad pair's now, so the last pair is planned without one.
    assert report.rows[3].verdict == 'missing'
    assert not report.passed
    limit = ('ERROR', {'kind': 'limit', 'topic': 'place_pose'})
    report = evaluate_run(outcomes(plans, limit), released_in_sequence(plans), HOME, CONFIG,
                          T0)
    assert report.rows[BAD].verdict == 'rejected_unexpected' and not report.passed


def test_an_invalid_message_and_a_stray_trajectory_are_reported(plans):
    received = released_in_sequence(plans)
    first = received[0].data
    renamed = JointTrajectoryData(('a', 'b', 'c'), first.time_from_start, first.positions,
                                  first.velocities, first.accelerations)
    received[0] = replace(received[0], data=renamed, problems=('header.frame_id wrong',))
    last = received[-1]
    stray = replace(last, receive_time=last.receive_time + last.data.duration + 0.01)
    report = evaluate_run(outcomes(plans), received + [stray], HOME, CONFIG, T0)
    assert report.rows[0].verdict == 'invalid'
    assert 'frame_id' in report.rows[0].reason and 'JTC rejects it' in report.rows[0].reason
    assert any('1 trajectories more than pairs planned' in failure
               for failure in report.failures)
    assert not report.passed


@pytest.mark.parametrize('limits, quantity', [
    (JointLimits(max_velocity=1.0, max_acceleration=200.0), 'velocity'),
    (JointLimits(max_velocity=10.0, max_acceleration=20.0), 'acceleration'),
])
def test_the_executed_command_is_checked_against_the_joint_limits(plans, limits, quantity):
    report = evaluate_run(outcomes(plans), released_in_sequence(plans), HOME,
                          replace(CONFIG, joint_limits=limits), T0)
    broken = [failure for failure in report.failures
              if failure.startswith('executed joint command')]
    assert len(broken) == 1 and quantity in broken[0]


def test_a_timeout_fails_the_run(plans):
    report = evaluate_run(outcomes(plans), released_in_sequence(plans), HOME, CONFIG, T0,
                          timed_out=True)
    assert not report.failures and not report.passed
    assert 'timeout' in format_report(report, CONFIG)
