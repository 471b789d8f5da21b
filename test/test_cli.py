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
"""The ``ellipath plan`` command: JSON output and errors."""

import json
import math

from ellipath_ros.cli import main
import pytest

EXAMPLE = ['plan', '--pick', '0', '0', '-0.8', '--place', '0.3', '0', '-0.75', '--json']


def run(capsys, argv):
    status = main(argv)
    out = capsys.readouterr().out
    return status, json.loads(out)


def test_plan_json_reproduces_the_paper_and_has_every_key(capsys):
    status, result = run(capsys, EXAMPLE)
    assert status == 0
    assert round(result['phi_deg'], 6) == 10.0
    assert (round(result['a'], 5), round(result['b'], 5)) == (0.15219, 0.03511)
    assert round(result['theta_T2_deg'], 3) == -2.329
    assert round(result['theta_T1_deg'], 3) == 177.671
    assert round(result['arc_length_approx'], 5) == 0.32058
    assert round(result['apex_height'], 5) == 0.06852
    # The default g2 join bends the ellipse's ends a little: its bend is slightly longer.
    assert result['path_length'] == pytest.approx(0.05 + result['segment_lengths'][1])
    assert 0.0 < result['segment_lengths'][1] - result['arc_length'] < 0.002
    assert len(result['apex']) == 3 and result['apex'][2] < 0
    for key in ('duration', 'planned.accel_jump_T1', 'planned.accel_jump_T2',
                'segment_durations', 'joint_names', 'executed.max_interpolation_error'):
        assert key in result
    for kind in ('planned', 'executed'):
        for key in ('peak_speed', 'peak_accel', 'peak_jerk', 'joint_peak_velocity',
                    'joint_peak_accel'):
            assert result[f'{kind}.{key}'] > 0.0
    rows = result['joint_trajectory']
    assert len(rows['time_from_start']) == len(rows['positions']) == len(rows['velocities'])
    assert all(len(row) == 3 for row in rows['accelerations'])


def test_curvature_profile_reports_the_papers_node_count(capsys):
    status, result = run(capsys, EXAMPLE + ['--profile', 'curvature', '--r', '0.77',
                                            '--join', 'paper'])
    assert status == 0 and result['n_nodes'] == 80 and result['profile'] == 'curvature'
    assert result['path_length'] == pytest.approx(0.05 + result['arc_length'])


def test_curvature_profile_refuses_the_g2_join(capsys):
    status, result = run(capsys, EXAMPLE + ['--profile', 'curvature'])
    assert status != 0 and result['error']['kind'] == 'invalid_input'
    assert result['error']['message'].startswith('join: expected paper')


@pytest.mark.parametrize('place, kind', [
    (['0', '0', '-0.8'], 'degenerate_geometry'),
    (['nan', '0', '-0.8'], 'invalid_input'),
    (['0.9', '0', '-0.8'], 'unreachable'),
])
def test_rejected_inputs_exit_2_with_an_error_object(capsys, place, kind):
    status, result = run(capsys, ['plan', '--pick', '0', '0', '-0.8', '--place', *place,
                                  '--json'])
    assert status == 2
    assert result['error']['kind'] == kind and 'expected' in result['error']['message']


def test_bad_option_value_is_rejected_with_its_name(capsys):
    status, result = run(capsys, EXAMPLE + ['--max-speed', '-1'])
    assert status == 2 and result['error']['message'].startswith('max_speed: expected')


def test_without_json_the_reason_goes_to_stderr(capsys):
    status = main(['plan', '--pick', '0', '0', '-0.8', '--place', '0', '0', '-0.8'])
    captured = capsys.readouterr()
    assert status == 2 and captured.out == '' and 'pick and place' in captured.err


@pytest.mark.parametrize('place', [['0.3', '0', '-0.8'], ['0.3', '0', '-0.85'],
                                   ['0', '0', '-0.7'], ['0.01', '0', '-0.6']])
def test_edge_cases_plan_without_nan(capsys, place):
    status, result = run(capsys, ['plan', '--pick', '0', '0', '-0.8', '--place', *place,
                                  '--json'])
    assert status == 0
    values = [value for value in result.values() if isinstance(value, float)]
    assert all(math.isfinite(value) for value in values)


@pytest.mark.parametrize('argv, text', [
    (['plan', '--pick', '0', '0', '--json'], '--pick'),
    (['plan', '--pick', '0', '0', '-0.8', '--json'], '--place'),
    (EXAMPLE + ['--max-speed', 'fast'], '--max-speed'),
    (EXAMPLE + ['--profile'], '--profile'),
    (EXAMPLE + ['--no-such-option'], '--no-such-option'),
])
def test_with_json_argument_errors_are_an_error_object_on_stdout(capsys, argv, text):
    status = main(argv)
    captured = capsys.readouterr()
    assert status == 2 and captured.err == ''
    error = json.loads(captured.out)['error']
    assert error['kind'] == 'invalid_arguments'
    assert error['message'].startswith('ellipath') and text in error['message']


def test_without_json_argument_errors_keep_argparses_usage_on_stderr(capsys):
    status = main(['plan', '--pick', '0', '0', '-0.8'])
    captured = capsys.readouterr()
    assert status == 2 and captured.out == ''
    assert captured.err.startswith('usage: ellipath plan') and '--place' in captured.err


@pytest.mark.parametrize('options, reason', [
    (['--workspace-z-max', '-0.72'], 'above workspace_z_max = -0.72 m'),
    (['--keep-out-boxes', '0.1', '-0.1', '-0.9', '0.2', '0.1', '-0.6'],
     r'inside keep_out_boxes[0] = [0.1, -0.1, -0.9, 0.2, 0.1, -0.6] m'),
])
def test_the_safe_workspace_options_reject_a_path_through_it(capsys, options, reason):
    status, result = run(capsys, EXAMPLE + options)
    assert status == 2 and result['error']['kind'] == 'workspace'
    assert result['error']['message'].startswith('executed TCP of the transfer leg[')
    assert reason in result['error']['message']


def test_keep_out_boxes_need_six_values_each(capsys):
    status, result = run(capsys, EXAMPLE + ['--keep-out-boxes', '0.1', '0.2'])
    assert status == 2
    assert result['error']['message'].startswith('keep_out_boxes: expected a multiple of 6')
