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

"""The node's parameter table, its validation and the parameter files (no ROS graph)."""

import math
from pathlib import Path

from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.settings import default_values
from ellipath_ros.core.settings import SETTINGS
from ellipath_ros.parameters import build_settings
from ellipath_ros.parameters import descriptor
from ellipath_ros.parameters import parameter_declarations
from ellipath_ros.parameters import PARAMETER_NAMES
from ellipath_ros.parameters import ROS_TYPES
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter import parameter_dict_from_yaml_file
import yaml

CONFIG = Path(__file__).resolve().parents[1] / 'config'
NODE_KEYS = {'frame_id', 'pairing', 'pick_dwell', 'place_dwell', 'home_position',
             'joint_state_timeout', 'header_stamp', 'queue_depth', 'controller_period',
             'release_lead', 'start_tolerance', 'conveyor_velocity', 'place_conveyor_velocity',
             'tracking_window_upstream', 'tracking_window_downstream', 'conveyor_twist_timeout',
             'conveyor_replan_tolerance', 'preplan_approach'}


def _yaml_parameters(name):
    """Return the ros__parameters of the ``/**`` section of a config file."""
    with open(CONFIG / name) as stream:
        document = yaml.safe_load(stream)
    assert list(document) == ['/**']
    return document['/**']['ros__parameters']


def test_one_parameter_per_setting_and_the_node_keys_have_no_core_field():
    assert PARAMETER_NAMES == tuple(setting.name for setting in SETTINGS)
    assert len(PARAMETER_NAMES) == len(set(PARAMETER_NAMES))
    assert {setting.name for setting in SETTINGS if not setting.owner} == NODE_KEYS
    declared = parameter_declarations()
    assert [name for name, _, _ in declared] == list(PARAMETER_NAMES)
    for (name, default, _), expected in zip(declared, default_values().values()):
        assert default == expected, name


@pytest.mark.parametrize('setting', SETTINGS, ids=lambda setting: setting.name)
def test_every_descriptor_follows_its_row(setting):
    result = descriptor(setting)
    default = default_values()[setting.name]
    if default == []:
        # rclpy types an empty list as a byte array: the row must accept any type.
        assert result.dynamic_typing
    else:
        assert Parameter.Type.from_parameter_value(default) == ROS_TYPES[setting.kind]
        assert not result.dynamic_typing
    assert result.name == setting.name
    assert result.type == ROS_TYPES[setting.kind].value
    assert result.description.startswith(setting.description)
    if setting.unit:
        assert f'[{setting.unit}]' in result.description
    if setting.kind == 'double':
        assert setting.unit, 'every float parameter has a unit'
        (interval,) = result.floating_point_range
        # rcl ranges are closed: the declared one is the closure of the row's range.
        assert (interval.from_value, interval.to_value) == (setting.low, setting.high)
        assert interval.from_value <= default <= interval.to_value
    if setting.kind == 'integer':
        (interval,) = result.integer_range
        assert (interval.from_value, interval.to_value) == (setting.low, setting.high)
    for bound in setting.open_bounds:
        # The description says which declared bound the node refuses.
        assert f'{bound:g} excluded' in result.description
        assert f'{bound:g} excluded' in result.additional_constraints
    if setting.allowed and setting.kind != 'double_array':
        assert result.additional_constraints.startswith(setting.allowed)
    if setting.choices:
        assert default in setting.choices
        assert result.additional_constraints == 'one of: ' + ', '.join(setting.choices)


def test_read_only_parameters():
    read_only = {name for name, _, result in parameter_declarations() if result.read_only}
    assert read_only == {'frame_id', 'joint_names', 'queue_depth'}


def test_defaults_of_the_issue():
    defaults = default_values()
    assert defaults['frame_id'] == 'base_link'
    assert defaults['pairing'] == 'stamp'
    assert defaults['header_stamp'] == 'ahead'
    assert defaults['controller_period'] == 0.002
    assert defaults['start_tolerance'] == 0.001
    assert defaults['home_position'] == [0.0, 0.0, -0.8]
    assert defaults['joint_state_timeout'] == 0.5
    assert defaults['queue_depth'] == 10
    assert defaults['pick_dwell'] == defaults['place_dwell'] == 0.0


def test_ellipath_yaml_lists_every_parameter_at_its_default():
    values = _yaml_parameters('ellipath.yaml')
    defaults = default_values()
    assert list(values) == list(PARAMETER_NAMES), 'same parameters, in table order'
    for setting in SETTINGS:
        value = values[setting.name]
        if value != []:
            assert Parameter.Type.from_parameter_value(value) == ROS_TYPES[setting.kind]
        assert value == defaults[setting.name], setting.name


def test_parameter_files_parse_with_rclpy():
    for name in ('ellipath.yaml', 'paper.yaml'):
        parsed = parameter_dict_from_yaml_file(str(CONFIG / name), use_wildcard=True)
        assert parsed and set(parsed) <= set(PARAMETER_NAMES)


def test_paper_yaml_selects_the_papers_method():
    values = _yaml_parameters('paper.yaml')
    assert values == {'arc_policy': 'paper', 'join': 'paper', 'profile': 'curvature',
                      'curvature_r': 0.77}
    settings = build_settings({**default_values(), **values})
    assert settings.planner.profile == 'curvature'


def test_defaults_build_valid_settings():
    settings = build_settings(default_values())
    assert settings.frame_id == 'base_link'
    assert settings.home_position == (0.0, 0.0, -0.8)
    assert settings.queue_depth == 10 and isinstance(settings.queue_depth, int)
    assert tuple(settings.planner.joint_names) == ('joint_1', 'joint_2', 'joint_3')


@pytest.mark.parametrize('name, value, reason', [
    ('pairing', 'random', 'pairing'),
    ('header_stamp', 'later', 'header_stamp'),
    ('header_stamp', 'now', 'header_stamp'),
    ('controller_period', 0.0, 'controller_period'),
    ('release_lead', -0.001, 'release_lead'),
    ('start_tolerance', 0.0, 'start_tolerance'),
    ('home_position', [0.0, 0.0], 'home_position'),
    ('home_position', [0.0, math.nan, -0.8], 'home_position'),
    ('pick_dwell', -1.0, 'pick_dwell'),
    ('place_dwell', math.inf, 'place_dwell'),
    ('joint_state_timeout', -0.1, 'joint_state_timeout'),
    ('queue_depth', 0, 'queue_depth'),
    ('frame_id', '', 'frame_id'),
    ('arc_policy', 'x', 'arc_policy'),
    ('profile', 'fast', 'profile'),
    ('max_speed', -1.0, 'max_speed'),
    ('joint_min', 2.0, 'joint'),  # valid alone, but above joint_max = 1.95
])
def test_an_invalid_set_is_rejected_naming_the_parameter(name, value, reason):
    with pytest.raises(EllipathError, match=reason):
        build_settings({**default_values(), name: value})


def test_a_missing_parameter_is_named():
    values = default_values()
    del values['max_jerk']
    with pytest.raises(EllipathError, match='max_jerk'):
        build_settings(values)
