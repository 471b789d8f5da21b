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
The node's parameters: one ROS parameter per row of the core's settings table.

The table (:data:`ellipath_ros.core.settings.SETTINGS`) holds every name, type, default,
unit, range and description; this module only turns its rows into ROS parameter descriptors
(:func:`parameter_declarations`) and a complete set of values into :class:`NodeSettings`
(:func:`build_settings`). ``config/ellipath.yaml`` and the README's table are generated from
the same rows (``scripts/settings_docs.py``).

Open bounds: rcl's ``FloatingPointRange`` has closed bounds only, so a range such as
``(0, 5]`` is declared as ``[0, 5]`` and the open end is refused by :func:`build_settings`,
which the node calls on every change (with the current values merged with the requested
ones, so a change is accepted or rejected as a whole). The descriptor's description and
``additional_constraints`` say so.
"""

from collections.abc import Sequence
from dataclasses import dataclass

from ellipath_ros.core.conveyor import Conveyor
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import require_point
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.settings import default_values
from ellipath_ros.core.settings import SETTINGS
from rcl_interfaces.msg import FloatingPointRange
from rcl_interfaces.msg import IntegerRange
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.parameter import Parameter

# The ROS parameter type of each kind of setting.
ROS_TYPES = {
    'bool': Parameter.Type.BOOL,
    'double': Parameter.Type.DOUBLE,
    'integer': Parameter.Type.INTEGER,
    'string': Parameter.Type.STRING,
    'double_array': Parameter.Type.DOUBLE_ARRAY,
    'string_array': Parameter.Type.STRING_ARRAY,
}
PARAMETER_NAMES = tuple(setting.name for setting in SETTINGS)


def _constraints(setting):
    """Return what a setting allows beyond its type, in words ('' for nothing)."""
    if not setting.allowed:
        return ''
    if setting.kind == 'double_array':
        return f'each value in {setting.allowed}'
    if not setting.open_bounds:
        return setting.allowed
    excluded = ' and '.join(f'{bound:g}' for bound in setting.open_bounds)
    # rcl ranges are closed: say which bound the declared range holds but the node refuses.
    return (f'{setting.allowed}: {excluded} excluded (the declared range includes it, the '
            'node refuses it)')


def descriptor(setting):
    """
    Return the rcl ParameterDescriptor of a row of the settings table.

    A numeric range is declared closed (``FloatingPointRange`` or ``IntegerRange``); an open
    bound is named in the description and ``additional_constraints``, and refused by
    :func:`build_settings`.
    """
    unit = f' [{setting.unit}]' if setting.unit else ''
    constraints = _constraints(setting)
    result = ParameterDescriptor(
        name=setting.name, type=ROS_TYPES[setting.kind].value, read_only=setting.read_only,
        description=setting.description + unit + (f'; {constraints}' if constraints else ''),
        additional_constraints=constraints)
    if setting.kind == 'double_array' and not setting.default:
        # rclpy types an empty list as a byte array and a YAML [] as not set: such a
        # parameter cannot be statically typed. build_settings checks its values instead.
        result.dynamic_typing = True
    if setting.kind == 'double' and setting.low is not None:
        result.floating_point_range = [FloatingPointRange(
            from_value=float(setting.low), to_value=float(setting.high), step=0.0)]
    elif setting.kind == 'integer' and setting.low is not None:
        result.integer_range = [IntegerRange(
            from_value=int(setting.low), to_value=int(setting.high), step=0)]
    return result


def parameter_declarations():
    """Return ``(name, default, descriptor)`` of every parameter, for declare_parameters."""
    defaults = default_values()
    return [(setting.name, defaults[setting.name], descriptor(setting))
            for setting in SETTINGS]


@dataclass(frozen=True)
class NodeSettings:
    """
    A validated, complete parameter set of the node.

    Parameters
    ----------
    planner : PlannerConfig
        Configuration of the planning core.
    frame_id : str
        Base frame of every pose and of the published trajectory.
    pairing : str
        ``'stamp'`` or ``'sequence'``.
    queue_depth : int
        Topic queue depth, most pending picks and most pairs in the cycle queue.
    header_stamp : str
        ``'zero'`` or ``'ahead'``.
    controller_period : float
        The controller's update period [s].
    release_lead : float
        Stamp ahead of publication with ``header_stamp`` ahead [s].
    start_tolerance : float
        Largest distance between the robot and a released trajectory's start [m].
    pick_dwell, place_dwell : float
        Pauses at the pick and place points [s].
    home_position : tuple of float
        TCP start used when nothing better is known [m].
    joint_state_timeout : float
        Age above which a joint state is not used as the start [s].
    conveyor : Conveyor
        Belt velocities (from the parameters) and the tracking window.
    conveyor_twist_timeout : float
        How long a conveyor_twist overrides conveyor_velocity [s].
    conveyor_replan_tolerance : float
        Belt velocity change that makes a held belt pick be re-planned at release [m/s].
    preplan_approach : bool
        Plan a pick's approach leg while its place is awaited.

    """

    planner: PlannerConfig
    frame_id: str
    pairing: str
    queue_depth: int
    header_stamp: str
    controller_period: float
    release_lead: float
    start_tolerance: float
    pick_dwell: float
    place_dwell: float
    home_position: tuple
    joint_state_timeout: float
    conveyor: Conveyor
    conveyor_twist_timeout: float
    conveyor_replan_tolerance: float
    preplan_approach: bool


def build_settings(values):
    """
    Validate a complete parameter set and return the settings it describes.

    Parameters
    ----------
    values : Mapping
        A value for every name of :data:`PARAMETER_NAMES`, by name; other keys are ignored.

    Returns
    -------
    NodeSettings
        The validated settings, with the core configuration built by
        ``PlannerConfig.from_flat``.

    Raises
    ------
    InvalidInputError
        A node parameter is invalid; the message names it.
    ellipath_ros.core.errors.EllipathError
        The core rejects its parameters; the message names the offending one.

    """
    missing = [name for name in PARAMETER_NAMES if name not in values]
    if missing:
        raise InvalidInputError(f'parameters: expected a value for every parameter, '
                                f'missing {", ".join(missing)}')
    node_values = {}
    core_values = {}
    for setting in SETTINGS:
        value = values[setting.name]
        if (setting.kind.endswith('_array') and isinstance(value, Sequence)
                and not isinstance(value, str)):
            value = list(value)  # rclpy may hand arrays over as array.array
        if setting.owner:
            core_values[setting.name] = value  # checked by the dataclass it feeds
        else:
            node_values[setting.name] = setting.check(value)
    home_position = require_point('home_position', node_values.pop('home_position'))
    conveyor = Conveyor(velocity=node_values.pop('conveyor_velocity'),
                        place_velocity=node_values.pop('place_conveyor_velocity'),
                        window_upstream=node_values.pop('tracking_window_upstream'),
                        window_downstream=node_values.pop('tracking_window_downstream'))
    return NodeSettings(planner=PlannerConfig.from_flat(core_values),
                        home_position=tuple(home_position.tolist()), conveyor=conveyor,
                        **node_values)
