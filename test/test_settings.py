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
The settings table is the one source: dataclasses, ROS descriptors, CLI, YAML and README.

The bound tests set every numeric setting to each end of its range, on the core (the
dataclass it feeds, or the node's build_settings for a node setting) and on a live
``EllipathNode`` (rcl's descriptor range, then the node's validation callback), and require
both to agree with the table: a closed bound is accepted, an open one refused, and a value
just outside a closed bound refused.
"""

import argparse
import math
import os
from pathlib import Path
import re
import sys

from ellipath_ros import cli
from ellipath_ros.core import geometry
from ellipath_ros.core import joint_trajectory
from ellipath_ros.core import sequencing
from ellipath_ros.core import timing
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.geometry import ArcPolicy
from ellipath_ros.core.kinematics import DeltaGeometry
from ellipath_ros.core.kinematics import JointLimits
from ellipath_ros.core.limits import CartesianLimits
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.settings import default_values
from ellipath_ros.core.settings import KINDS
from ellipath_ros.core.settings import SECTIONS
from ellipath_ros.core.settings import SETTING_BY_NAME
from ellipath_ros.core.settings import SETTINGS
from ellipath_ros.core.settings import validate
from ellipath_ros.core.workspace import SafeWorkspace
from ellipath_ros.node import EllipathNode
from ellipath_ros.parameters import build_settings
import pytest
from rclpy.exceptions import InvalidParameterValueException
from rclpy.parameter import Parameter
import yaml

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(__file__)), 'scripts'))
import settings_docs  # noqa: E402, I100 (scripts/ is not a package)

ROS_DOMAIN_OFFSET = 0  # see conftest.py; the nodes here are never spun
ROOT = Path(__file__).resolve().parents[1]
OWNERS = {'DeltaGeometry': DeltaGeometry, 'JointLimits': JointLimits,
          'CartesianLimits': CartesianLimits, 'ArcPolicy': ArcPolicy,
          'SafeWorkspace': SafeWorkspace, 'PlannerConfig': PlannerConfig}
NUMERIC = [setting for setting in SETTINGS if setting.kind in ('double', 'integer')]
# Other settings a bound needs to form a valid set (the forearm must reach past the offset).
COMPANIONS = {('base_radius', 'high'): {'forearm': 10.0},
              ('effector_radius', 'high'): {'forearm': 10.0}}
# Bounds that the range allows but a rule between two settings always refuses, by the setting
# the rule's message names: joint_min < joint_max, workspace_z_min < workspace_z_max,
# tracking_window_upstream < tracking_window_downstream.
CONFLICTS = {('joint_min', 'high'): 'joint_max', ('joint_max', 'low'): 'joint_max',
             ('workspace_z_min', 'high'): 'workspace_z_max',
             ('workspace_z_max', 'low'): 'workspace_z_max',
             ('tracking_window_upstream', 'high'): 'tracking_window_downstream',
             ('tracking_window_downstream', 'low'): 'tracking_window_downstream'}
BOUND_CASES = [(setting, side) for setting in NUMERIC for side in ('low', 'high')]


def _case_id(case):
    setting, side = case
    return f'{setting.name}-{side}'


def _core_result(values):
    """Return None if the core accepts the values (a node setting: build_settings), else why."""
    try:
        if all(SETTING_BY_NAME[name].owner for name in values):
            PlannerConfig.from_flat(values)
        else:
            build_settings({**default_values(), **values})
    except EllipathError as error:
        return str(error)
    return None


def _node_result(context, values):
    """Return None if a live node takes the values, else rcl's or the node's reason."""
    read_only = any(SETTING_BY_NAME[name].read_only for name in values)
    overrides = [Parameter(name, value=value) for name, value in values.items()]
    try:
        node = EllipathNode(context=context, parameter_overrides=overrides if read_only else [])
    except (EllipathError, InvalidParameterValueException) as error:
        return str(error)
    try:
        if read_only:
            return None
        result = node.set_parameters_atomically(overrides)
        if result.successful:
            for name, value in values.items():
                assert node.get_parameter(name).value == value
            return None
        return result.reason
    finally:
        node.destroy_node()


@pytest.mark.parametrize('case', BOUND_CASES, ids=_case_id)
def test_the_core_and_the_descriptor_agree_with_the_table_at_each_bound(ros_context, case):
    setting, side = case
    bound = setting.low if side == 'low' else setting.high
    is_open = setting.low_open if side == 'low' else setting.high_open
    values = {setting.name: type(setting.default)(bound),
              **COMPANIONS.get((setting.name, side), {})}
    core, node = _core_result(values), _node_result(ros_context, values)
    range_message = f'{setting.name}: expected a value in {setting.allowed}'
    if is_open:
        assert core is not None and core.startswith(range_message), core
        assert node is not None and range_message in node, node
    elif (setting.name, side) in CONFLICTS:
        # In range, refused by the rule between two settings, by both alike.
        rule = f'{CONFLICTS[setting.name, side]}: expected a value >'
        assert core is not None and core.startswith(rule), core
        assert node is not None and rule in node, node
    else:
        assert core is None and node is None, (core, node)


@pytest.mark.parametrize('case', BOUND_CASES, ids=_case_id)
def test_just_outside_a_bound_both_refuse_and_the_core_names_the_range(ros_context, case):
    setting, side = case
    bound = setting.low if side == 'low' else setting.high
    step = max(abs(bound), setting.high - setting.low) * 1e-3
    if setting.kind == 'integer':
        step = 1
    value = type(setting.default)(bound - step if side == 'low' else bound + step)
    values = {setting.name: value, **COMPANIONS.get((setting.name, side), {})}
    unit = f' {setting.unit}' if setting.unit else ''
    message = f'{setting.name}: expected a value in {setting.allowed}{unit}, got {value!r}'
    assert _core_result(values) == message
    assert _node_result(ros_context, values) is not None


def test_the_open_bounds_of_the_issue():
    for name in ('base_radius', 'apex_clearance', 'min_radius', 'curvature_r'):
        assert SETTING_BY_NAME[name].open_bounds == (0.0,), name
    with pytest.raises(InvalidInputError, match=re.escape('base_radius: expected a value in '
                                                          '(0, 5] m, got 0.0')):
        DeltaGeometry(base_radius=0.0)
    with pytest.raises(InvalidInputError, match=re.escape('curvature_r: expected a value in '
                                                          '(0, 1000] rad/m, got 0.0')):
        PlannerConfig(curvature_r=0.0)


@pytest.mark.parametrize('setting', [setting for setting in SETTINGS if setting.choices],
                         ids=lambda setting: setting.name)
def test_a_value_outside_the_choices_is_refused_naming_them(setting):
    expected = f"{setting.name}: expected one of: {', '.join(setting.choices)}, got 'other'"
    with pytest.raises(InvalidInputError) as error:
        validate(setting.name, 'other')
    assert str(error.value) == expected
    assert _core_result({setting.name: 'other'}) == expected


@pytest.mark.parametrize('setting', [setting for setting in SETTINGS if setting.owner],
                         ids=lambda setting: setting.name)
def test_every_core_setting_feeds_its_field_and_the_default_is_the_fields(setting):
    owner = OWNERS[setting.owner]
    default = getattr(owner(), setting.attribute)
    expected = setting.default
    assert (list(default) if isinstance(default, tuple) else default) == (
        list(expected) if isinstance(expected, tuple) else expected)
    if setting.kind == 'double':
        value = setting.default * 1.01 if setting.default else (setting.low + setting.high) / 2
        config = PlannerConfig.from_flat({setting.name: value})
        sections = {type(getattr(config, name)).__name__: getattr(config, name)
                    for name in ('geometry', 'joint_limits', 'limits', 'arc', 'workspace')}
        holder = sections.get(setting.owner, config)
        assert getattr(holder, setting.attribute) == value


def test_the_choices_the_other_modules_hold_are_the_tables():
    assert set(geometry.ARC_POLICIES) == set(SETTING_BY_NAME['arc_policy'].choices)
    assert set(geometry.JOINS) == set(SETTING_BY_NAME['join'].choices)
    assert set(timing.PROFILES) == set(SETTING_BY_NAME['profile'].choices)
    assert set(sequencing.PAIRING_MODES) == set(SETTING_BY_NAME['pairing'].choices)
    assert set(sequencing.HEADER_STAMPS) == set(SETTING_BY_NAME['header_stamp'].choices)
    assert joint_trajectory.DEFAULT_JOINT_NAMES == SETTING_BY_NAME['joint_names'].default
    assert geometry.DEFAULT_JOIN_TOLERANCE == SETTING_BY_NAME['join_tolerance'].default


def test_config_yaml_is_generated_from_the_table():
    text = (ROOT / 'config' / 'ellipath.yaml').read_text()
    assert text == settings_docs.render_yaml(), 'run python3 scripts/settings_docs.py'
    values = yaml.safe_load(text)['/**']['ros__parameters']
    assert values == default_values()
    # Each comment (the lines right above its key) gives the unit and what the row allows.
    comments = {}
    pending = []
    parameter_lines = [line for line in text.splitlines() if line.startswith('    ') or not line]
    for line in parameter_lines:
        stripped = line.strip()
        if stripped.startswith('# ---') or not stripped:
            pending = []
        elif stripped.startswith('#'):
            pending.append(stripped[1:].strip())
        elif pending:
            comments[stripped.split(':')[0]] = ' '.join(pending)
            pending = []
    assert list(comments) == [setting.name for setting in SETTINGS]
    for setting in SETTINGS:
        comment = comments[setting.name]
        assert comment.startswith(setting.description), setting.name
        if setting.allowed:
            assert setting.allowed.lower() in comment.lower(), setting.name
        if setting.unit:
            assert re.search(rf'[ \[]{re.escape(setting.unit)}[\].]', comment), setting.name
        assert ('Read-only.' in comment) == setting.read_only, setting.name


def test_readme_parameter_table_is_the_tables():
    readme = (ROOT / 'README.md').read_text()
    assert settings_docs.readme_with_table(readme) == readme, 'run scripts/settings_docs.py'
    start = readme.index(settings_docs.README_BEGIN)
    rows = readme[start:readme.index(settings_docs.README_END)].splitlines()[3:]
    assert len(rows) == len(SETTINGS)
    for row, setting in zip(rows, SETTINGS):
        cells = [cell.strip().replace('\\|', '|') for cell in row.strip('|').split(' | ')]
        name, kind, default, unit, allowed, field, description = cells
        assert name.split()[0] == f'`{setting.name}`'
        assert ('(read-only)' in name) == setting.read_only
        assert yaml.safe_load(default.strip('`')) == default_values()[setting.name]
        assert (kind, unit, description) == (setting.kind, setting.unit, setting.description)
        assert allowed.endswith(setting.allowed)
        assert field == (f'`{setting.owner}.{setting.attribute}`' if setting.owner else 'node')


def test_the_settings_docs_script_reports_a_file_out_of_step(tmp_path, monkeypatch):
    stale = tmp_path / 'ellipath.yaml'
    stale.write_text(settings_docs.render_yaml().replace('max_speed: 4.0', 'max_speed: 5.0'))
    monkeypatch.setattr(settings_docs, 'YAML_PATH', stale)
    monkeypatch.setattr(settings_docs, 'ROOT', tmp_path)
    readme = tmp_path / 'README.md'
    readme.write_text('# x\n' + settings_docs.render_readme_table())
    monkeypatch.setattr(settings_docs, 'README_PATH', readme)
    assert settings_docs.main(['--check']) == 1
    assert settings_docs.main([]) == 0
    assert stale.read_text() == settings_docs.render_yaml()
    assert settings_docs.main(['--check']) == 0


def test_the_cli_offers_an_option_per_planner_setting_with_its_default_and_range():
    parser = argparse.ArgumentParser()
    cli._add_plan_arguments(parser)
    options = {action.dest: action for action in parser._actions}
    offered = [setting for setting in SETTINGS if setting.cli]
    assert {setting.name for setting in offered} == {
        setting.name for setting in SETTINGS if setting.owner} - {'joint_names'}
    for setting in offered:
        action = options[setting.name]
        assert action.option_strings == [setting.cli]
        assert action.default == (list(setting.default) if isinstance(setting.default, tuple)
                                  else setting.default)
        assert setting.allowed in action.help
    args = parser.parse_args(['--pick', '0', '0', '-0.8', '--place', '0.3', '0', '-0.75',
                              '--base-radius', '0.21', '--r', '2', '--arc', 'min_radius'])
    config = cli._config_from(args)
    assert (config.geometry.base_radius, config.curvature_r, config.arc.kind) == (
        0.21, 2.0, 'min_radius')
    args = parser.parse_args(['--pick', '0', '0', '-0.8', '--place', '0.3', '0', '-0.75',
                              '--min-radius', '0'])
    with pytest.raises(InvalidInputError, match=re.escape('min_radius: expected a value in '
                                                          '(0, 2] m, got 0.0')):
        cli._config_from(args)


def test_an_array_setting_checks_each_value_against_the_range():
    with pytest.raises(InvalidInputError, match=re.escape(
            'keep_out_boxes[4]: expected a value in [-10, 10] m, got 11.0')):
        SafeWorkspace(keep_out_boxes=[0.0, 0.0, -1.0, 0.1, 11.0, -0.9])
    assert validate('keep_out_boxes', (1.0, -2.0)) == [1.0, -2.0]
    with pytest.raises(InvalidInputError, match='queue_depth: expected an integer'):
        validate('queue_depth', 2.5)
    with pytest.raises(InvalidInputError, match="frame_id: expected a non-empty name, got ''"):
        validate('frame_id', '')
    assert math.isclose(SETTING_BY_NAME['joint_max'].high, math.pi)


def test_every_row_is_well_formed():
    assert len({setting.name for setting in SETTINGS}) == len(SETTINGS)
    for setting in SETTINGS:
        assert setting.kind in KINDS and setting.section in SECTIONS, setting.name
        assert setting.description and not setting.description.endswith('.'), setting.name
        if setting.kind in ('double', 'integer'):
            assert setting.low < setting.high, setting.name
            validate(setting.name, setting.default)
        if setting.owner:
            assert setting.owner in OWNERS and setting.attribute, setting.name


def test_the_readmes_plan_commands_run_as_pasted(capsys):
    readme = (ROOT / 'README.md').read_text()
    commands = re.findall(r'^ellipath plan (.*?)(?:\s+#.*)?$', readme, re.M)
    assert len(commands) >= 4
    for command in commands:
        assert cli.main(['plan', *command.split()]) == 0, (command, capsys.readouterr().err)
