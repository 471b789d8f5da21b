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
Every setting of the planner and of the node: one declarative table, and its validator.

Each row of :data:`SETTINGS` gives a setting's name, type, default, unit, allowed range (each
bound open or closed) or choices, description, and the dataclass field it feeds (none for the
node's own settings). Everything else follows from it:

* the core's frozen dataclasses check their fields with :func:`validate_fields` (messages
  "<name>: expected <range>, got <value>"); checks between fields stay in the dataclass;
* ``ellipath_ros/parameters.py`` declares one ROS parameter per row;
* ``ellipath`` (``cli.py``) offers an option for each row that names one;
* ``config/ellipath.yaml`` and the README's parameter table are generated from it
  (``scripts/settings_docs.py``) and a test keeps them in step.

No ROS here: the table is plain data.
"""

from dataclasses import dataclass
import math

from .errors import InvalidInputError, require_finite

# Types of a setting, named as the ROS parameter types they become.
KINDS = ('bool', 'double', 'integer', 'string', 'double_array', 'string_array')
# Section titles, in order; each row names one by its key.
SECTIONS = {
    'ros': 'ROS interface',
    'geometry': 'robot geometry and joint position limits (DeltaGeometry)',
    'path': 'path',
    'timing': 'timing: TCP and joint limits',
    'output': 'trajectory output',
    'workspace': 'safe workspace (every plan is checked against it as executed)',
    'conveyor': 'conveyor tracking (belt picks and places)',
}


def _number(value):
    """Format a bound or default for people: pi by name, else the shortest form."""
    if abs(value) == math.pi:
        return '-pi' if value < 0 else 'pi'
    return f'{value:g}'


@dataclass(frozen=True)
class Setting:
    """
    One setting: a row of :data:`SETTINGS`.

    Parameters
    ----------
    name : str
        Flat name, as the ROS parameter and in messages.
    kind : str
        One of :data:`KINDS`.
    default : bool or float or int or str or tuple
        Default value (a tuple for the array kinds).
    unit : str
        SI unit, ``''`` for unitless values.
    description : str
        What it does, one or two sentences.
    section : str
        Key of :data:`SECTIONS`.
    low, high : float or None
        Bounds of a number (of each element of a ``double_array``); None: none.
    low_open, high_open : bool
        Whether the bound itself is excluded.
    choices : tuple of str
        Allowed values of a string.
    owner, attribute : str
        Class name and field of the dataclass this setting feeds; ``''`` for a setting of the
        node alone.
    read_only : bool
        The node reads it at start-up only.
    cli : str
        Option of ``ellipath plan``/``plot`` that sets it, ``''`` for none.

    """

    name: str
    kind: str
    default: bool | float | int | str | tuple
    unit: str
    description: str
    section: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple = ()
    owner: str = ''
    attribute: str = ''
    read_only: bool = False
    cli: str = ''

    @property
    def allowed(self):
        """Return the allowed values in words: ``'(0, 5]'``, ``'one of: a, b'`` or ``''``."""
        if self.choices:
            return 'one of: ' + ', '.join(self.choices)
        if self.low is None:
            return ''
        left = '(' if self.low_open else '['
        right = ')' if self.high_open else ']'
        return f'{left}{_number(self.low)}, {_number(self.high)}{right}'

    @property
    def open_bounds(self):
        """Return the bounds this setting excludes, as a tuple of numbers."""
        return tuple(bound for bound, is_open in ((self.low, self.low_open),
                                                  (self.high, self.high_open)) if is_open)

    def check_number(self, value, label=None):
        """
        Return ``value`` as a float within this setting's range, or raise.

        ``label`` names the value in the message (default: the setting's name), e.g. an
        element of an array setting.
        """
        label = label or self.name
        number = require_finite(label, value)
        too_low = number <= self.low if self.low_open else number < self.low
        too_high = number >= self.high if self.high_open else number > self.high
        if too_low or too_high:
            unit = f' {self.unit}' if self.unit else ''
            shown = value if isinstance(value, int) else number  # an integer stays one
            raise InvalidInputError(
                f'{label}: expected a value in {self.allowed}{unit}, got {shown!r}')
        return number

    def check(self, value):
        """
        Return ``value`` checked against this row and converted to its kind, or raise.

        Booleans must be ``True`` or ``False``, numbers finite and in range (an integer
        whole), strings among the choices (or, without choices, non-empty). The elements of
        a ``double_array`` are checked against the range; sizes of arrays are the owner's to
        check.

        Raises
        ------
        InvalidInputError
            The message names the setting, what it allows and what it got.

        """
        if self.kind == 'bool':
            if not isinstance(value, bool):
                raise InvalidInputError(f'{self.name}: expected true or false, got {value!r}')
            return value
        if self.kind == 'string':
            if self.choices and value not in self.choices:
                raise InvalidInputError(f'{self.name}: expected {self.allowed}, got {value!r}')
            if not isinstance(value, str) or not value:
                raise InvalidInputError(f'{self.name}: expected a non-empty name, got {value!r}')
            return value
        if self.kind == 'double':
            return self.check_number(value)
        if self.kind == 'integer':
            number = self.check_number(value)
            if not number.is_integer():
                raise InvalidInputError(f'{self.name}: expected an integer, got {value!r}')
            return int(number)
        if isinstance(value, (str, bytes)) or not hasattr(value, '__iter__'):
            raise InvalidInputError(f'{self.name}: expected a list, got {value!r}')
        if self.kind == 'double_array' and self.low is not None:
            return [self.check_number(item, f'{self.name}[{index}]')
                    for index, item in enumerate(value)]
        return list(value)


def _row(name, kind, default, unit, description, section, *, feeds='', **options):
    """Build a row; ``feeds`` is ``'Owner.attribute'`` of the dataclass field it sets."""
    owner, _, attribute = feeds.partition('.')
    return Setting(name, kind, default, unit, description, section, owner=owner,
                   attribute=attribute, **options)


def _core(name, kind, default, unit, description, section, feeds=None, **options):
    """Build the row of a planner setting, offered by the CLI as ``--name-with-dashes``."""
    options.setdefault('cli', '--' + name.replace('_', '-'))
    return _row(name, kind, default, unit, description, section,
                feeds=feeds or f'PlannerConfig.{name}', **options)


SETTINGS = (
    # --- the node's ROS interface -----------------------------------------------------------
    _row('frame_id', 'string', 'base_link', '',
         'Robot base frame; pick and place poses in any other frame are rejected (no tf2)',
         'ros', read_only=True),
    _core('joint_names', 'string_array', ('joint_1', 'joint_2', 'joint_3'), '',
          'Actuator joint names of arms 0, 1, 2, in trajectory order; 3 distinct names',
          'ros', read_only=True, cli=''),
    _row('pairing', 'string', 'stamp', '',
         'How a place_pose finds its pick_pose: stamp = the pick with the identical '
         'header.stamp (a lost message never mis-pairs), sequence = the pending pick (a lost '
         'place joins the next place with the wrong pick); pick_place pairs need neither',
         'ros', choices=('stamp', 'sequence')),
    _row('queue_depth', 'integer', 10, '',
         'Most pairs in the cycle queue (waiting to be planned, being planned and held; when '
         'it is full the newest pair is rejected with a WARN status) and depth of the '
         'published topics (the pose topics are read RELIABLE/KEEP_ALL, see '
         'docs/reliability.md)', 'ros', low=1, high=1000, read_only=True),
    _row('header_stamp', 'string', 'ahead', '',
         "Trajectory header.stamp. Jazzy's joint_trajectory_controller replaces a running "
         'trajectory at its next cycle whatever the stamp, so each trajectory is published '
         'only once the one before it has ended. ahead = publication + release_lead (the '
         'controller holds the robot still until then: the start, hence the end, is known '
         'exactly), or, published during the previous final dwell (place_dwell >= '
         'release_lead), the end of that dwell: no idle time; zero = start at the control '
         'cycle that picks it up (assumed within controller_period of publication; a later '
         "delivery lets the next trajectory cut this one's last milliseconds)", 'ros',
         choices=('zero', 'ahead')),
    _row('controller_period', 'double', 0.002, 's',
         "The controller's update period: a zero-stamped trajectory starts at most this long "
         'after publication, and the next one is released at that latest end', 'ros',
         low=1e-4, high=0.1),
    _row('release_lead', 'double', 0.004, 's',
         'header_stamp ahead: stamp = publication + this; must exceed transport plus one '
         'controller period', 'ros', low=0.0, high=1.0),
    _row('start_tolerance', 'double', 0.001, 'm',
         'At release, a held trajectory whose start is further than this from where the '
         'robot is (fresh joint_states) is re-planned from there, or dropped', 'ros',
         low=1e-5, high=0.1),
    _row('pick_dwell', 'double', 0.0, 's', 'Pause at the pick point', 'ros',
         low=0.0, high=10.0),
    _row('place_dwell', 'double', 0.0, 's', 'Pause at the place point', 'ros',
         low=0.0, high=10.0),
    _row('home_position', 'double_array', (0.0, 0.0, -0.8), 'm',
         'TCP start position (x, y, z) when neither a fresh joint state nor a previous '
         'trajectory is known', 'ros'),
    _row('joint_state_timeout', 'double', 0.5, 's',
         'Joint states older than this (by arrival time) are ignored, as the start and at '
         'release; also the longest wait at release for a joint state measured after the '
         'previous motion when the last one showed the robot off it; 0 never uses them',
         'ros', low=0.0, high=60.0),
    _row('preplan_approach', 'bool', True, '',
         'Plan the approach leg (from where the robot will be to the pick) when a pick_pose '
         'arrives, while the node waits for its place_pose and no pair waits to be planned, '
         'so that only the transfer leg is planned after the place; reused if the pair starts '
         'within start_tolerance of it with the same pick and parameters (static belts '
         'only; pick_place pairs are planned in one go)', 'ros'),
    # --- conveyor tracking ------------------------------------------------------------------
    _row('conveyor_velocity', 'double_array', (0.0, 0.0, 0.0), 'm/s',
         'Pick belt velocity (vx, vy, vz) in the base frame, speed at most 2 m/s; zero = '
         'static picks. A fresh conveyor_twist overrides it. A pick header.stamp is the time '
         'the object was at that position (zero = on receipt)', 'conveyor'),
    _row('place_conveyor_velocity', 'double_array', (0.0, 0.0, 0.0), 'm/s',
         'Place belt (tray) velocity in the base frame, at any angle to the pick belt, speed '
         'at most 2 m/s; zero = static places. The place is where the tray is at the place '
         'instant; at an angle the pick dwell is extended a little to meet it exactly',
         'conveyor'),
    _row('tracking_window_upstream', 'double', -0.3, 'm',
         'Tracking window: upstream limit along the pick belt direction (TCP position '
         'projected on the unit belt velocity); an object upstream of it is picked as it '
         'enters', 'conveyor', low=-10.0, high=10.0),
    _row('tracking_window_downstream', 'double', 0.3, 'm',
         'Tracking window: downstream limit, above the upstream one; an object that would '
         'pass it before the robot can be on it is rejected as missed', 'conveyor',
         low=-10.0, high=10.0),
    _row('conveyor_twist_timeout', 'double', 0.5, 's',
         'A conveyor_twist (geometry_msgs/TwistStamped, linear part, base frame) overrides '
         'conveyor_velocity for this long after its arrival; 0 never uses it', 'conveyor',
         low=0.0, high=60.0),
    _row('conveyor_replan_tolerance', 'double', 0.001, 'm/s',
         'A held belt pick planned for a belt velocity further than this from the current '
         'one is planned again, with those held after it, while the robot runs; at release '
         'at the latest (as is one whose planned start has passed)', 'conveyor',
         low=0.0, high=1.0),
    # --- robot geometry and joint position limits -------------------------------------------
    _core('base_radius', 'double', 0.2, 'm', 'R: base centre to actuator axis', 'geometry',
          'DeltaGeometry.base_radius', low=0.0, low_open=True, high=5.0),
    _core('effector_radius', 'double', 0.045, 'm', 'r: effector centre (TCP) to forearm joint',
          'geometry', 'DeltaGeometry.effector_radius', low=0.0, low_open=True, high=5.0),
    _core('upper_arm', 'double', 0.35, 'm', 'L1: upper arm length', 'geometry',
          'DeltaGeometry.upper_arm', low=0.0, low_open=True, high=5.0),
    _core('forearm', 'double', 0.8, 'm',
          'L2: forearm (parallelogram) length; must exceed |base_radius - effector_radius|',
          'geometry', 'DeltaGeometry.forearm', low=0.0, low_open=True, high=10.0),
    _core('joint_min', 'double', -0.85, 'rad',
          'Lowest joint angle (q = 0 horizontal, q > 0 points the arm down)', 'geometry',
          'DeltaGeometry.joint_min', low=-math.pi, high=math.pi),
    _core('joint_max', 'double', 1.95, 'rad', 'Highest joint angle; above joint_min',
          'geometry', 'DeltaGeometry.joint_max', low=-math.pi, high=math.pi),
    # --- path -------------------------------------------------------------------------------
    _core('pick_clearance', 'double', 0.025, 'm', 'c1: vertical rise above the pick point',
          'path', low=0.0, high=1.0),
    _core('place_clearance', 'double', 0.025, 'm', 'c2: vertical descent onto the place point',
          'path', low=0.0, high=1.0),
    _core('arc_policy', 'string', 'paper', '',
          "Choice of the ellipse: paper = the paper's rule, apex_clearance = apex this high "
          'above the upper tangent point, min_radius = smallest radius of curvature this large',
          'path', 'ArcPolicy.kind', choices=('paper', 'apex_clearance', 'min_radius'),
          cli='--arc'),
    _core('apex_clearance', 'double', 0.025, 'm',
          'Apex height above the upper tangent point (arc_policy apex_clearance)', 'path',
          'ArcPolicy.apex_clearance', low=0.0, low_open=True, high=2.0),
    _core('min_radius', 'double', 0.02, 'm',
          'Smallest radius of curvature of the arc (arc_policy min_radius)', 'path',
          'ArcPolicy.min_radius', low=0.0, low_open=True, high=2.0),
    _core('join', 'string', 'g2', '',
          'Line-to-arc joins T1/T2: g2 = curvature-continuous transitions (no acceleration '
          "step, bounded jerk), paper = the paper's path (acceleration step bounded by "
          'max_accel_jump)', 'path', choices=('g2', 'paper')),
    _core('join_tolerance', 'double', 5e-4, 'm',
          "Largest distance of the g2 path from the paper's path (join g2)", 'path',
          low=1e-6, high=0.01),
    # --- timing -----------------------------------------------------------------------------
    _core('profile', 'string', 'time_optimal', '',
          'Motion profile on the arc: time_optimal = jerk-limited time-optimal, curvature = '
          "the paper's radius-of-curvature method (needs join paper; see config/paper.yaml)",
          'timing', choices=('curvature', 'time_optimal')),
    _core('curvature_r', 'double', 0.77, 'rad/m',
          "Gain r of the paper's profile: parameter step = r * radius of curvature "
          '(profile curvature)', 'timing', low=0.0, low_open=True, high=1000.0, cli='--r'),
    _core('max_speed', 'double', 4.0, 'm/s', 'TCP speed limit', 'timing',
          'CartesianLimits.max_speed', low=0.01, high=100.0),
    _core('max_accel', 'double', 50.0, 'm/s^2', 'TCP acceleration limit (vector norm)',
          'timing', 'CartesianLimits.max_accel', low=0.1, high=1e4),
    _core('max_jerk', 'double', 5000.0, 'm/s^3', 'TCP jerk limit (vector norm)', 'timing',
          'CartesianLimits.max_jerk', low=1.0, high=1e7),
    _core('max_accel_jump', 'double', 25.0, 'm/s^2',
          'Largest normal acceleration jump allowed at the line-to-arc joins T1 and T2 (join '
          'paper; a g2 join has none); 0 stops the motion there', 'timing',
          'CartesianLimits.max_accel_jump', low=0.0, high=1e4),
    _core('max_joint_velocity', 'double', 10.0, 'rad/s', 'Joint speed limit', 'timing',
          'JointLimits.max_velocity', low=0.01, high=1000.0),
    _core('max_joint_accel', 'double', 200.0, 'rad/s^2', 'Joint acceleration limit', 'timing',
          'JointLimits.max_acceleration', low=0.1, high=1e5),
    # --- trajectory output ------------------------------------------------------------------
    _core('output_mode', 'string', 'knots', '',
          'Trajectory points: knots = as few as knot_tolerance allows, samples = one every '
          'sample_period', 'output', choices=('knots', 'samples')),
    _core('knot_tolerance', 'double', 1e-4, 'm',
          "Largest TCP deviation of the controller's interpolation between knots (knots mode)",
          'output', low=1e-7, high=0.01),
    _core('sample_period', 'double', 0.004, 's', 'Time between points (output_mode samples)',
          'output', low=1e-4, high=0.1),
    # --- safe workspace ---------------------------------------------------------------------
    _core('workspace_radius', 'double', 0.4, 'm',
          'Largest TCP distance from the base axis (vertical cylinder)', 'workspace',
          'SafeWorkspace.radius', low=0.001, high=10.0),
    _core('workspace_z_min', 'double', -1.0, 'm', 'Lowest TCP height', 'workspace',
          'SafeWorkspace.z_min', low=-10.0, high=10.0),
    _core('workspace_z_max', 'double', -0.55, 'm',
          'Highest TCP height; above workspace_z_min', 'workspace', 'SafeWorkspace.z_max',
          low=-10.0, high=10.0),
    _core('keep_out_boxes', 'double_array', (), 'm',
          'Axis-aligned boxes the TCP must not enter, 6 values per box: xmin, ymin, zmin, '
          'xmax, ymax, zmax (empty: none). The TCP may touch a face: inflate the boxes by '
          'the size of the tool', 'workspace',
          'SafeWorkspace.keep_out_boxes', low=-10.0, high=10.0),
)

SETTING_BY_NAME = {setting.name: setting for setting in SETTINGS}
# The settings of the planning core, in table order (those that feed a dataclass field).
CORE_NAMES = tuple(setting.name for setting in SETTINGS if setting.owner)


def default_values(core_only=False):
    """
    Return a new dict of the defaults, by name, arrays as lists (as ROS holds them).

    Parameters
    ----------
    core_only : bool
        Only the settings of the planning core (:data:`CORE_NAMES`).

    """
    return {setting.name: (list(setting.default) if isinstance(setting.default, tuple)
                           else setting.default)
            for setting in SETTINGS if setting.owner or not core_only}


def validate(name, value):
    """Return ``value`` checked against the row ``name`` (see :meth:`Setting.check`)."""
    return SETTING_BY_NAME[name].check(value)


def validate_fields(instance):
    """
    Check and convert, in place, every scalar field of a frozen dataclass that a row feeds.

    The rows are those whose ``owner`` is the name of the instance's class (or of the nearest
    base class that has rows). Array fields are left to the owner (their sizes and structure
    are its own).

    Raises
    ------
    InvalidInputError
        The first field out of its row's range; the message names the setting.

    """
    owner = next((cls.__name__ for cls in type(instance).__mro__
                  if cls.__name__ in _SCALARS_BY_OWNER), None)
    for setting in _SCALARS_BY_OWNER.get(owner, ()):
        value = setting.check(getattr(instance, setting.attribute))
        object.__setattr__(instance, setting.attribute, value)


def default_of(name):
    """Return the default of the setting ``name`` (for dataclass field defaults)."""
    return SETTING_BY_NAME[name].default


# Owner class name -> its rows of a scalar kind, which validate_fields checks.
_SCALARS_BY_OWNER = {
    owner: tuple(setting for setting in SETTINGS if setting.owner == owner
                 and setting.kind in ('double', 'integer', 'string'))
    for owner in dict.fromkeys(setting.owner for setting in SETTINGS if setting.owner)}
