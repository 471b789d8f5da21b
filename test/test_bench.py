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
``ellipath bench``: the shape and internal consistency of its report, never its timings.

One quick run with three pairs (two of them sent to a node process on this module's domain,
conftest.py: 46 + 38 by default) gives the JSON object that the tests check: the required
keys, latency figures that are ordered and counted, cycle ratios that are durations over
bounds, picks per minute that are 60 s over the cycle time.
"""

import json
import math
import os
from pathlib import Path
import platform
import subprocess
import sys

from ellipath_ros.bench import format_report
from ellipath_ros.bench.e2e import PICK_LEAD
from ellipath_ros.bench.latency import latency_stats
from ellipath_ros.bench.latency import MIN_HORIZONTAL_OFFSET
from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.bench.latency import WORKSPACE_RADIUS
from ellipath_ros.bench.latency import WORKSPACE_Z
from ellipath_ros.malloc_policy import MALLOC_ENVIRONMENT
import numba
import numpy as np
import pytest

ROS_DOMAIN_OFFSET = 38  # see conftest.py
PAIRS = 3
E2E_PAIRS = 2
TIMEOUT = 240.0  # s, the whole quick run on a loaded machine
ROOT = Path(__file__).resolve().parents[1]
LATENCY_KEYS = {'request_ms', 'leg_ms', 'curvature_request_ms', 'message_ms', 'e2e_ms'}
CYCLE_KEYS = {'case', 'profile', 'join', 'max_accel_jump', 'duration_s', 'topp_ra_bound_s',
              'ratio_to_bound'}


def _bench(env, *options):
    """Run ``python -m ellipath_ros.cli bench`` on this source tree; return the process."""
    env = dict(env)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(ROOT), env.get('PYTHONPATH')]))
    return subprocess.run([sys.executable, '-m', 'ellipath_ros.cli', 'bench', *options],
                          env=env, cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT)


@pytest.fixture(scope='module')
def report(ros_env, ros_domain_id):
    pytest.importorskip('toppra')
    process = _bench(ros_env, '--json', '--quick', '--pairs', str(PAIRS), '--e2e-pairs',
                     str(E2E_PAIRS), '--domain-id', str(ros_domain_id))
    assert process.returncode == 0, process.stderr + process.stdout
    lines = process.stdout.splitlines()
    assert len(lines) == 1, process.stdout
    return json.loads(lines[0]), process.stderr


def test_the_json_object_has_the_required_keys(report):
    result, _ = report
    assert {'latency', 'cycle', 'executed', 'picks_per_min', 'machine'} <= set(result)
    # Beside the required keys: e2e less the node's plan_time of each pair, and from the pick.
    assert set(result['latency']) == LATENCY_KEYS | {'e2e_outside_plan_ms', 'e2e_from_pick_ms'}
    for stats in result['latency'].values():
        assert set(stats) == {'p50', 'p99', 'max', 'n'}
    for row in result['cycle']:
        assert CYCLE_KEYS <= set(row)


def test_latencies_are_ordered_and_counted(report):
    result, _ = report
    latency, notes, pairs = result['latency'], result['latency_notes'], result['pairs']
    for name, stats in latency.items():
        assert isinstance(stats['n'], int) and stats['n'] >= 1, name
        assert 0.0 < stats['p50'] <= stats['p99'] <= stats['max'], name
    assert pairs['drawn'] == PAIRS
    request = notes['request_ms']
    assert latency['request_ms']['n'] == pairs['planned']
    if not request['budget_reached']:
        assert pairs['planned'] + sum(request['rejected'].values()) == PAIRS
    # Message, legs and curvature requests are measured on the planned requests.
    assert latency['message_ms']['n'] == pairs['planned']
    assert latency['leg_ms']['n'] <= pairs['planned']
    assert latency['curvature_request_ms']['n'] <= pairs['planned']
    e2e = notes['e2e_ms']
    assert e2e['requested'] == min(E2E_PAIRS, pairs['planned'])
    assert e2e['mismatched'] == 0
    if not e2e['budget_reached']:
        assert latency['e2e_ms']['n'] == e2e['requested']
    # The node's plan of each pair lies inside its end-to-end time.
    outside = latency['e2e_outside_plan_ms']
    assert outside['n'] == latency['e2e_ms']['n']
    assert outside['max'] < latency['e2e_ms']['max']
    # Each pick goes out at least PICK_LEAD before its place.
    from_pick = latency['e2e_from_pick_ms']
    assert from_pick['n'] == latency['e2e_ms']['n']
    assert from_pick['p50'] >= latency['e2e_ms']['p50'] + PICK_LEAD * 1e3
    assert 0 <= e2e['approach_preplanned'] <= latency['e2e_ms']['n']


def test_the_bench_plans_under_the_nodes_malloc_policy(report, ros_env):
    result, _ = report
    # As ellipath_node: set on glibc unless the environment chose a policy of its own.
    chosen = any(name in ros_env for name in MALLOC_ENVIRONMENT)
    glibc = platform.libc_ver()[0] == 'glibc'
    assert result['latency_notes']['node_malloc_policy'] is (glibc and not chosen)


def test_executed_peaks_are_ratios_to_the_limits(report):
    result, _ = report
    executed = result['executed']
    assert 'executed' in executed['what'] and 'JTC' in executed['what']
    assert 1 <= executed['n'] <= result['pairs']['planned']
    for ratio, peak, limit in (('speed', 'peak_speed', 4.0), ('accel', 'peak_accel', 50.0),
                               ('jerk', 'peak_jerk', 5000.0)):
        assert executed[ratio] == pytest.approx(executed[peak] / limit)
        assert executed[ratio] > 0.0
    # The planner keeps JTC's interpolated speed within 5 % of the limit.
    assert executed['speed'] <= 1.06


def test_message_sizes_are_those_of_the_planned_requests(report):
    result, _ = report
    messages = result['messages']
    assert messages['n'] == result['pairs']['planned']
    for name in ('points', 'bytes'):
        assert 0 < messages[name]['p50'] <= messages[name]['p99'] <= messages[name]['max']
    # A request holds both legs (at least two points each) and the CDR header and names.
    assert messages['points']['p50'] >= 4
    assert messages['bytes']['max'] > 48 * messages['points']['max']
    assert f"max {messages['points']['max']};" in format_report(result)


def test_cycle_ratios_are_durations_over_the_bound(report):
    result, _ = report
    rows = result['cycle']
    cases = {(row['case'], row['max_accel_jump'], row['profile']) for row in rows}
    assert cases == {(case, jump, profile)
                     for case in ("paper's example", '25-305-25 mm') for jump in (5.0, 25.0)
                     for profile in ('time_optimal', 'curvature')}
    for row in rows:
        assert row['join'] in ('paper', 'g2')
        assert row['ratio_to_bound'] == pytest.approx(row['duration_s'] / row['topp_ra_bound_s'])
        # No motion along the path beats TOPP-RA's bound without jerk limit.
        assert row['ratio_to_bound'] >= 1.0
        if 'topp_ra_bound_join_capped_s' in row:
            assert row['topp_ra_bound_join_capped_s'] >= row['topp_ra_bound_s']
    by_key = {(row['case'], row['join'], row['max_accel_jump'], row['profile']): row
              for row in rows}
    for (case, join, jump, profile), row in by_key.items():
        if profile == 'curvature':
            fast = by_key[(case, join, jump, 'time_optimal')]
            assert row['duration_s'] > fast['duration_s']
            assert row['topp_ra_bound_s'] == fast['topp_ra_bound_s']


def test_picks_per_minute_follow_from_the_cycle_time(report):
    result, _ = report
    picks = result['picks_per_min']
    assert picks['dwell_s'] == [0.035, 0.035]
    rows = {(row['limits'], row['join']): row for row in picks['rows']}
    assert {limits for limits, _ in rows} == {'default', 'fast'}
    for (limits, join), row in rows.items():
        # A cycle holds two legs and two dwells.
        assert row['cycle_s'] > 0.07
        assert row['picks_per_min'] == pytest.approx(60.0 / row['cycle_s'])
        assert rows[('fast', join)]['cycle_s'] < rows[('default', join)]['cycle_s']
    assert rows[('fast', 'paper')]['max_speed'] == 10.0
    assert rows[('fast', 'paper')]['joint_limits'] == 'lifted'
    reference = picks['reference']
    assert reference['picks_per_min'] == [150, 160]
    assert 'quoted' in reference['source']


def test_machine_names_the_versions(report):
    result, _ = report
    machine = result['machine']
    assert machine['cores'] == os.cpu_count()
    assert machine['python'] == platform.python_version()
    assert machine['numpy'] == np.__version__
    assert machine['numba'] == numba.__version__
    assert machine['ruckig'] and machine['cpu']


def test_progress_goes_to_stderr(report):
    _, stderr = report
    for section in ('cycle', 'request', 'leg', 'curvature request', 'message', 'executed',
                    'e2e'):
        assert f'ellipath bench: {section} ' in stderr


def test_the_human_report_shows_every_section(report):
    result, _ = report
    text = format_report(result)
    for name, stats in result['latency'].items():
        assert f"| {name[:-3]} | {stats['p50']:.1f} | {stats['p99']:.1f} |" in text
    assert text.count("| paper's example |") == text.count('| 25-305-25 mm |') > 0
    assert "executed (JTC's quintic" in text
    assert '150-160' in text and 'quoted' in text


def test_bad_counts_are_argument_errors(ros_env):
    process = _bench(ros_env, '--json', '--pairs', '0')
    assert process.returncode == 2
    error = json.loads(process.stdout)['error']
    assert error['kind'] == 'invalid_arguments' and '--pairs' in error['message']


def test_random_pairs_are_seeded_and_in_the_workspace():
    pairs = random_pairs(200, seed=7)
    assert len(pairs) == 200
    again = random_pairs(200, seed=7)
    assert all(np.array_equal(a, b) for pair, other in zip(pairs, again)
               for a, b in zip(pair, other))
    assert not np.array_equal(random_pairs(1, seed=8)[0][0], pairs[0][0])
    points = np.array([point for pair in pairs for point in pair])
    assert np.hypot(points[:, 0], points[:, 1]).max() <= WORKSPACE_RADIUS
    assert WORKSPACE_Z[0] <= points[:, 2].min() and points[:, 2].max() <= WORKSPACE_Z[1]
    offsets = [np.hypot(*(place - pick)[:2]) for pick, place in pairs]
    assert min(offsets) >= MIN_HORIZONTAL_OFFSET


def test_latency_stats_of_known_times():
    # 1, 2, ..., 100 ms: linear interpolation puts p50 at 50.5 ms and p99 at 99.01 ms.
    stats = latency_stats([value * 1e-3 for value in range(1, 101)])
    assert stats['n'] == 100
    assert stats['p50'] == pytest.approx(50.5)
    assert stats['p99'] == pytest.approx(99.01)
    assert stats['max'] == pytest.approx(100.0)
    assert latency_stats([]) == {'p50': None, 'p99': None, 'max': None, 'n': 0}
    assert not math.isnan(latency_stats([0.001])['p99'])
