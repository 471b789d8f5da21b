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
The node's parameters: one declarative table, and the validation of a complete set.

Every parameter of ``ellipath_node`` is one row of :data:`PARAMETER_TABLE`: name, ROS type,
default, unit, description, range and whether it is read-only. The rows of the planning core
take their defaults from :data:`ellipath_ros.core.planner.CORE_DEFAULTS`, so the defaults live
in one place; ``config/ellipath.yaml`` repeats them for users and a test keeps the two equal.

:func:`build_settings` turns a complete set of values into :class:`NodeSettings`; the node
calls it at start-up and on every run-time change, with the current values merged with the
requested ones, so a change is accepted or rejected as a whole.
"""

from collections.abc import Sequence
from dataclasses import dataclass
import math

from ellipath_ros.core.conveyor import Conveyor
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import require_point
from ellipath_ros.core.errors import require_range
from ellipath_ros.core.geometry import ARC_POLICIES
from ellipath_ros.core.geometry import JOINS
from ellipath_ros.core.planner import CORE_DEFAULTS
from ellipath_ros.core.planner import OUTPUT_MODES
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.sequencing import HEADER_STAMPS
from ellipath_ros.core.sequencing import PAIRING_MODES
from ellipath_ros.core.timing import PROFILES
from rcl_interfaces.msg import FloatingPointRange
from rcl_interfaces.msg import IntegerRange
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.parameter import Parameter

_DOUBLE = Parameter.Type.DOUBLE
_INTEGER = Parameter.Type.INTEGER
_STRING = Parameter.Type.STRING
_DOUBLE_ARRAY = Parameter.Type.DOUBLE_ARRAY
_STRING_ARRAY = Parameter.Type.STRING_ARRAY


@dataclass(frozen=True)
class ParameterSpec:
    """
    One parameter of the node.

    Parameters
    ----------
    name : str
        Parameter name (flat, no namespace).
    type_ : rclpy.parameter.Parameter.Type
        ROS parameter type; the default is converted to it.
    default : object
        Default value.
    unit : str
        SI unit, or ``''`` for unitless values.
    description : str
        What the parameter does, for ``ros2 param describe``.
    low, high : float or int or None
        Closed range of a numeric parameter (enforced by rclpy through the descriptor).
    choices : tuple of str
        Allowed values of a string parameter.
    read_only : bool
        True for parameters that cannot change after start-up.
    core : bool
        True for parameters of the planning core (validated by ``PlannerConfig.from_flat``).

    """

    name: str
    type_: Parameter.Type
    default: object
    unit: str
    description: str
    low: object = None
    high: object = None
    choices: tuple = ()
    read_only: bool = False
    core: bool = False

    def descriptor(self):
        """Return the rcl ParameterDescriptor of this parameter."""
        descriptor = ParameterDescriptor(
            name=self.name, type=self.type_.value, read_only=self.read_only,
            description=f'{self.description} [{self.unit}]' if self.unit else self.description)
        if self.type_ == _DOUBLE_ARRAY and not self.default:
            # rclpy types an empty list as a byte array and a YAML [] as not set: such a
            # parameter cannot be statically typed. build_settings checks its values instead.
            descriptor.dynamic_typing = True
        if self.choices:
            descriptor.additional_constraints = 'one of: ' + ', '.join(self.choices)
        if self.type_ == _DOUBLE and self.low is not None:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(self.low), to_value=float(self.high), step=0.0)]
        elif self.type_ == _INTEGER and self.low is not None:
            descriptor.integer_range = [IntegerRange(
                from_value=int(self.low), to_value=int(self.high), step=0)]
        return descriptor


def _as_type(type_, value):
    """Convert ``value`` to the Python value rclpy expects for ``type_``."""
    if type_ == _DOUBLE:
        return float(value)
    if type_ == _INTEGER:
        return int(value)
    if type_ == _STRING:
        return str(value)
    if type_ == _DOUBLE_ARRAY:
        return [float(item) for item in value]
    if type_ == _STRING_ARRAY:
        return [str(item) for item in value]
    raise TypeError(f'unsupported parameter type {type_}')


def _node(name, type_, default, unit, description, **options):
    """Build the row of a parameter owned by the ROS node."""
    return ParameterSpec(name, type_, _as_type(type_, default), unit, description, **options)


def _core(name, type_, unit, description, **options):
    """Build the row of a core parameter; its default comes from CORE_DEFAULTS."""
    return ParameterSpec(name, type_, _as_type(type_, CORE_DEFAULTS[name]), unit, description,
                         core=True, **options)


PARAMETER_TABLE = (
    # ROS interface.
    _node('frame_id', _STRING, 'base_link', '',
          'Robot base frame; pick and place poses in any other frame are rejected (no tf2)',
          read_only=True),
    _core('joint_names', _STRING_ARRAY, '',
          'Actuator joint names of arms 0, 1, 2, in trajectory order', read_only=True),
    _node('pairing', _STRING, 'stamp', '',
          'How a place_pose finds its pick_pose: stamp = the pick with the identical '
          'header.stamp (a lost message never mis-pairs), sequence = the pending pick (a '
          'lost place joins the next place with the wrong pick); pick_place pairs need '
          'neither', choices=PAIRING_MODES),
    _node('queue_depth', _INTEGER, 10, '',
          'Most pairs in the cycle queue (waiting to be planned, being planned and held; when '
          'it is full the newest pair is rejected with a WARN status), most picks waiting for '
          'their place, and depth of the published topics (the pose topics are read through '
          'queues of 1000)', low=1, high=1000, read_only=True),
    _node('header_stamp', _STRING, 'ahead', '',
          "Trajectory header.stamp. Jazzy's joint_trajectory_controller replaces a running "
          'trajectory at its next cycle whatever the stamp, so each trajectory is published '
          'only once the one before it has ended. ahead = publication + release_lead (the '
          'controller holds the robot still until then: the start, hence the end, is known '
          'exactly), or, published during the previous final dwell (place_dwell >= '
          'release_lead), the end of that dwell: no idle time; zero = start at the control '
          'cycle that picks it up (assumed within controller_period of publication; a later '
          "delivery lets the next trajectory cut this one's last milliseconds)",
          choices=HEADER_STAMPS),
    _node('controller_period', _DOUBLE, 0.002, 's',
          "The controller's update period: a zero-stamped trajectory starts at most this long "
          'after publication, and the next one is released at that latest end', low=1e-4,
          high=0.1),
    _node('release_lead', _DOUBLE, 0.004, 's',
          'header_stamp ahead: stamp = publication + this; must exceed transport plus one '
          'controller period', low=0.0, high=1.0),
    _node('start_tolerance', _DOUBLE, 0.001, 'm',
          'At release, a held trajectory whose start is further than this from where the '
          'robot is (fresh joint_states) is re-planned from there, or dropped', low=1e-5,
          high=0.1),
    _node('pick_dwell', _DOUBLE, 0.0, 's', 'Pause at the pick point', low=0.0, high=10.0),
    _node('place_dwell', _DOUBLE, 0.0, 's', 'Pause at the place point', low=0.0, high=10.0),
    _node('home_position', _DOUBLE_ARRAY, [0.0, 0.0, -0.8], 'm',
          'TCP start position (x, y, z) when neither a fresh joint state nor a previous '
          'trajectory is known'),
    _node('joint_state_timeout', _DOUBLE, 0.5, 's',
          'Joint states older than this (by arrival time) are ignored, as the start and at '
          'release; also the longest wait at release for a joint state measured after the '
          'previous motion when the last one showed the robot off it; 0 never uses them',
          low=0.0, high=60.0),
    # Conveyor tracking (issue 12).
    _node('conveyor_velocity', _DOUBLE_ARRAY, [0.0, 0.0, 0.0], 'm/s',
          'Pick belt velocity (vx, vy, vz) in the base frame; zero = static picks. A fresh '
          'conveyor_twist overrides it. A pick header.stamp is the time the object was at '
          'that position (zero = on receipt)'),
    _node('place_conveyor_velocity', _DOUBLE_ARRAY, [0.0, 0.0, 0.0], 'm/s',
          'Place belt (tray) velocity in the base frame, zero or parallel to the pick belt; '
          'zero = static places'),
    _node('tracking_window_upstream', _DOUBLE, Conveyor().window_upstream, 'm',
          'Tracking window: upstream limit along the pick belt direction (TCP position '
          'projected on the unit belt velocity); an object upstream of it is picked as it '
          'enters', low=-10.0, high=10.0),
    _node('tracking_window_downstream', _DOUBLE, Conveyor().window_downstream, 'm',
          'Tracking window: downstream limit; an object that would pass it before the robot '
          'can be on it is rejected as missed', low=-10.0, high=10.0),
    _node('conveyor_twist_timeout', _DOUBLE, 0.5, 's',
          'A conveyor_twist (geometry_msgs/TwistStamped, linear part, base frame) overrides '
          'conveyor_velocity for this long after its arrival; 0 never uses it', low=0.0,
          high=60.0),
    _node('conveyor_replan_tolerance', _DOUBLE, 0.001, 'm/s',
          'At release, a belt pick planned for a belt velocity further than this from the '
          'current one is re-planned (as is one whose planned start has passed)', low=0.0,
          high=1.0),
    # Robot geometry and joint position limits.
    _core('base_radius', _DOUBLE, 'm', 'Base centre to actuator axis (R)', low=0.0, high=5.0),
    _core('effector_radius', _DOUBLE, 'm', 'Effector centre (TCP) to forearm joint (r)',
          low=0.0, high=5.0),
    _core('upper_arm', _DOUBLE, 'm', 'Upper arm length (L1)', low=0.0, high=5.0),
    _core('forearm', _DOUBLE, 'm', 'Forearm (parallelogram) length (L2)', low=0.0, high=10.0),
    _core('joint_min', _DOUBLE, 'rad', 'Lowest joint angle (q > 0 points the arm down)',
          low=-math.pi, high=math.pi),
    _core('joint_max', _DOUBLE, 'rad', 'Highest joint angle', low=-math.pi, high=math.pi),
    # Path.
    _core('pick_clearance', _DOUBLE, 'm', 'Vertical rise above the pick point (c1)',
          low=0.0, high=1.0),
    _core('place_clearance', _DOUBLE, 'm', 'Vertical descent onto the place point (c2)',
          low=0.0, high=1.0),
    _core('arc_policy', _STRING, '',
          "Choice of the ellipse: paper = the paper's rule, apex_clearance = apex this high "
          'above the upper tangent point, min_radius = smallest radius of curvature this large',
          choices=ARC_POLICIES),
    _core('apex_clearance', _DOUBLE, 'm', 'Apex height above the upper tangent point '
          '(arc_policy apex_clearance)', low=0.0, high=2.0),
    _core('min_radius', _DOUBLE, 'm', 'Smallest radius of curvature of the arc '
          '(arc_policy min_radius)', low=0.0, high=2.0),
    _core('join', _STRING, '',
          'Line-to-arc joins T1/T2: g2 = curvature-continuous transitions (no acceleration '
          "step, bounded jerk), paper = the paper's path (acceleration step bounded by "
          'max_accel_jump)', choices=JOINS),
    _core('join_tolerance', _DOUBLE, 'm',
          "Largest distance of the g2 path from the paper's path (join g2)", low=1e-6,
          high=0.01),
    # Timing.
    _core('profile', _STRING, '',
          'Motion profile on the arc: time_optimal = jerk-limited time-optimal, curvature = '
          "the paper's radius-of-curvature method", choices=PROFILES),
    _core('curvature_r', _DOUBLE, 'rad/m',
          "Gain r of the paper's profile: parameter step = r * radius of curvature "
          '(profile curvature)', low=0.0, high=1000.0),
    _core('max_speed', _DOUBLE, 'm/s', 'TCP speed limit', low=0.01, high=100.0),
    _core('max_accel', _DOUBLE, 'm/s^2', 'TCP acceleration norm limit', low=0.1, high=1.0e4),
    _core('max_jerk', _DOUBLE, 'm/s^3', 'TCP jerk limit', low=1.0, high=1.0e7),
    _core('max_accel_jump', _DOUBLE, 'm/s^2',
          'Largest normal acceleration jump allowed at the line-to-arc joins T1 and T2 '
          '(join paper; a g2 join has none)',
          low=0.0, high=1.0e4),
    _core('max_joint_velocity', _DOUBLE, 'rad/s', 'Joint speed limit', low=0.01,
          high=1000.0),
    _core('max_joint_accel', _DOUBLE, 'rad/s^2', 'Joint acceleration limit',
          low=0.1, high=1.0e5),
    # Trajectory output.
    _core('output_mode', _STRING, '',
          'Trajectory points: knots = as few as knot_tolerance allows, samples = one every '
          'sample_period', choices=OUTPUT_MODES),
    _core('knot_tolerance', _DOUBLE, 'm',
          "Largest TCP deviation of the controller's interpolation between knots (knots mode)",
          low=1e-7, high=0.01),
    _core('sample_period', _DOUBLE, 's', 'Time between points (output_mode samples)',
          low=1e-4, high=0.1),
    # Safe workspace: every plan is checked against it as executed (JTC's interpolation).
    _core('workspace_radius', _DOUBLE, 'm',
          'Safe workspace: largest TCP distance from the base axis', low=0.001, high=10.0),
    _core('workspace_z_min', _DOUBLE, 'm', 'Safe workspace: lowest TCP height',
          low=-10.0, high=10.0),
    _core('workspace_z_max', _DOUBLE, 'm', 'Safe workspace: highest TCP height',
          low=-10.0, high=10.0),
    _core('keep_out_boxes', _DOUBLE_ARRAY, 'm',
          'Axis-aligned boxes the TCP must not enter, 6 values per box: xmin, ymin, zmin, '
          'xmax, ymax, zmax (empty: none)'),
)

PARAMETER_NAMES = tuple(spec.name for spec in PARAMETER_TABLE)


def parameter_defaults():
    """Return the default of every parameter, by name."""
    return {spec.name: spec.default for spec in PARAMETER_TABLE}


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


def _check_node_value(spec, value):
    """Return the node-owned ``value`` checked against its row, or raise InvalidInputError."""
    if spec.choices:
        if value not in spec.choices:
            raise InvalidInputError(
                f'{spec.name}: expected one of {", ".join(spec.choices)}, got {value!r}')
        return value
    if spec.low is None:
        return value
    number = require_range(spec.name, value, spec.low, spec.high, unit=spec.unit)
    if spec.type_ == _INTEGER:
        if not number.is_integer():
            raise InvalidInputError(f'{spec.name}: expected an integer, got {value!r}')
        return int(number)
    return number


def build_settings(values):
    """
    Validate a complete parameter set and return the settings it describes.

    Parameters
    ----------
    values : Mapping[str, object]
        A value for every name of :data:`PARAMETER_TABLE`; other keys are ignored.

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
    for spec in PARAMETER_TABLE:
        value = values[spec.name]
        if (spec.type_ in (_DOUBLE_ARRAY, _STRING_ARRAY) and isinstance(value, Sequence)
                and not isinstance(value, str)):
            value = list(value)  # rclpy may hand arrays over as array.array
        if spec.core:
            core_values[spec.name] = value
        else:
            node_values[spec.name] = _check_node_value(spec, value)
    if not node_values['frame_id']:
        raise InvalidInputError("frame_id: expected a frame name, got ''")
    home_position = require_point('home_position', node_values.pop('home_position'))
    conveyor = Conveyor(velocity=node_values.pop('conveyor_velocity'),
                        place_velocity=node_values.pop('place_conveyor_velocity'),
                        window_upstream=node_values.pop('tracking_window_upstream'),
                        window_downstream=node_values.pop('tracking_window_downstream'))
    return NodeSettings(planner=PlannerConfig.from_flat(core_values),
                        home_position=tuple(home_position.tolist()), conveyor=conveyor,
                        **node_values)
