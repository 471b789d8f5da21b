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
Property-based tests of the core (hypothesis): hostile numbers, degenerate geometry, bad sets.

Properties: nothing raises but an :class:`EllipathError` subclass, whose message names the
offending value; every returned trajectory passes the JTC rules (``validate_jtc``), the joint
limits on JTC's interpolation (``check_joint_limits`` with interior samples) and the safe
workspace on the executed motion, and starts where the robot is and ends at the place.

Budget: planning costs about 50 ms per valid cycle, so the planning properties are capped at
a few hundred examples; the cheap validators run thousands. The profile ``ci`` (default) is
derandomized, so every run tries the same inputs; ``ELLIPATH_HYPOTHESIS_PROFILE=explore``
draws new ones, ten times as many (see docs/reliability.md for the counts and run time).
"""

import math
import os

from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import require_point
from ellipath_ros.core.errors import require_range
from ellipath_ros.core.errors import UnreachableError
from ellipath_ros.core.errors import WorkspaceError
from ellipath_ros.core.joint_trajectory import check_joint_limits
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import quintic_positions
from ellipath_ros.core.joint_trajectory import REST_TOLERANCE
from ellipath_ros.core.joint_trajectory import validate_jtc
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.kinematics import reachable
from ellipath_ros.core.planner import _EXECUTED_WORKSPACE_TOLERANCE
from ellipath_ros.core.planner import _QUINTIC_CHECK_SAMPLES
from ellipath_ros.core.planner import _WORKSPACE_CHECK_PERIOD
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import plan_transfer
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.settings import CORE_NAMES
from ellipath_ros.core.settings import default_values
from ellipath_ros.core.workspace import SafeWorkspace
from ellipath_ros.parameters import build_settings
from hypothesis import assume
from hypothesis import event
from hypothesis import given
from hypothesis import HealthCheck
from hypothesis import settings
from hypothesis import strategies as st
import numpy as np

settings.register_profile(
    'ci', derandomize=True, database=None, deadline=None,
    suppress_health_check=(HealthCheck.too_slow,))
settings.register_profile(
    'explore', database=None, deadline=None, suppress_health_check=(HealthCheck.too_slow,))
settings.load_profile(os.environ.get('ELLIPATH_HYPOTHESIS_PROFILE', 'ci'))
SCALE = 10 if os.environ.get('ELLIPATH_HYPOTHESIS_PROFILE') == 'explore' else 1

CHEAP = 1200 * SCALE  # examples of a validator property (microseconds each)
MEDIUM = 400 * SCALE  # examples that build a config or fail early in the planner
PLANS = 150 * SCALE  # examples that may plan a whole cycle (~50 ms each)
CONFIG_PLANS = 30 * SCALE  # examples that plan with a random configuration (up to 1 s each)

HOME = np.array([0.0, 0.0, -0.8])
# Where the executed TCP is compared with the end points [m].
END_TOLERANCE = 1e-6

# Hostile floats: NaN, +-inf, huge, tiny and subnormal values, and everything in between.
hostile_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True),
    st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1e-300, 1e300,
                     -1e300, 1.7976931348623157e308, math.nan, math.inf, -math.inf]))
# Things that are not numbers at all.
non_numbers = st.one_of(st.none(), st.text(max_size=5), st.booleans(),
                        st.lists(st.floats(), max_size=2), st.just(object()))
coordinates = st.floats(min_value=-0.5, max_value=0.5, allow_nan=False)
heights = st.floats(min_value=-1.1, max_value=-0.45, allow_nan=False)
# Points around the default workspace (some outside it, some out of reach).
around = st.tuples(coordinates, coordinates, heights).map(np.array)
# Points low in the workspace, where most arcs between two of them stay inside it.
inside = st.tuples(st.floats(0.0, 0.3), st.floats(0.0, 2.0 * math.pi),
                   st.floats(-1.0, -0.78)).map(
    lambda polar: np.array([polar[0] * math.cos(polar[1]), polar[0] * math.sin(polar[1]),
                            polar[2]]))
# Three in four inside: most examples plan, the others are rejected for a reason.
points = st.one_of(inside, inside, inside, around)


def _assert_names(error, *names):
    """Assert that ``error`` is an EllipathError whose message names one of ``names``."""
    assert isinstance(error, EllipathError), repr(error)
    message = str(error)
    assert any(name in message for name in names), (names, message)
    assert ': expected ' in message, message


# --- cheap validators --------------------------------------------------------------------

@settings(max_examples=CHEAP)
@given(value=st.one_of(hostile_floats, non_numbers, st.integers()),
       low=st.floats(-1e6, 1e6), width=st.floats(0.0, 1e6))
def test_require_range_returns_a_value_in_range_or_names_it(value, low, width):
    high = low + width
    try:
        result = require_range('speed', value, low, high, unit='m/s')
    except InvalidInputError as error:
        _assert_names(error, 'speed')
        assert 'got' in str(error)
        return
    assert isinstance(result, float) and math.isfinite(result) and low <= result <= high


@settings(max_examples=CHEAP)
@given(value=st.one_of(
    st.lists(hostile_floats, min_size=0, max_size=5),
    st.lists(st.lists(st.floats(), max_size=3), max_size=3),
    non_numbers))
def test_require_point_returns_three_finite_coordinates_or_names_them(value):
    try:
        point = require_point('pick', value)
    except InvalidInputError as error:
        _assert_names(error, 'pick')
        return
    assert point.shape == (3,) and np.isfinite(point).all()


@settings(max_examples=CHEAP)
@given(radius=hostile_floats, z_min=hostile_floats, z_max=hostile_floats,
       boxes=st.lists(hostile_floats, max_size=13))
def test_a_workspace_is_valid_or_names_its_bad_value(radius, z_min, z_max, boxes):
    try:
        workspace = SafeWorkspace(radius, z_min, z_max, boxes)
    except InvalidInputError as error:
        _assert_names(error, 'workspace_radius', 'workspace_z_min', 'workspace_z_max',
                      'keep_out_boxes')
        return
    assert 0.0 < workspace.radius and workspace.z_min < workspace.z_max
    assert all(box[axis] < box[axis + 3] for box in workspace.keep_out_boxes
               for axis in range(3))


@settings(max_examples=CHEAP)
@given(tcp=st.lists(st.tuples(hostile_floats, hostile_floats, hostile_floats), min_size=1,
                    max_size=4),
       box=st.tuples(*[st.floats(-1.0, 1.0)] * 3, *[st.floats(0.001, 0.5)] * 3))
def test_the_workspace_check_names_the_first_point_outside(tcp, box):
    low = np.array(box[:3])
    workspace = SafeWorkspace(keep_out_boxes=[*low, *(low + np.array(box[3:]))])
    inside = workspace.contains(tcp)
    try:
        workspace.check(tcp, name='tcp', times=np.arange(len(tcp)) * 0.5)
    except WorkspaceError as error:
        assert not inside[error.index] and inside[:error.index].all()
        assert str(error).startswith(f'tcp[{error.index}] at t = {error.index * 0.5:.4f} s: '
                                     'expected a point within the safe workspace')
        return
    assert inside.all()


@settings(max_examples=CHEAP)
@given(point=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.5, 0.2)))
def test_inverse_then_forward_kinematics_returns_the_point_or_names_it(point):
    geometry = PlannerConfig().geometry
    try:
        q = inverse_kinematics(point, geometry, name='tcp')
    except UnreachableError as error:
        _assert_names(error, 'tcp')
        assert not reachable(point, geometry)
        return
    assert reachable(point, geometry)
    assert np.all((geometry.joint_min <= q) & (q <= geometry.joint_max))
    np.testing.assert_allclose(forward_kinematics(q, geometry), point, atol=1e-9)


@settings(max_examples=CHEAP)
@given(q=st.tuples(*[st.one_of(st.floats(-0.85, 1.95), hostile_floats)] * 3))
def test_forward_then_inverse_kinematics_returns_the_point_or_names_the_angles(q):
    geometry = PlannerConfig().geometry
    try:
        point = forward_kinematics(q, geometry, name='q')
    except EllipathError as error:
        _assert_names(error, 'q')
        return
    assert np.isfinite(point).all()
    if reachable(point, geometry):
        again = forward_kinematics(inverse_kinematics(point, geometry), geometry)
        np.testing.assert_allclose(again, point, atol=1e-9)


def _valid_trajectory():
    """Return the joint trajectory of one default cycle (planned once per session)."""
    if not hasattr(_valid_trajectory, 'cached'):
        _valid_trajectory.cached = plan_cycle(
            HOME, [0.1, 0.05, -0.85], [-0.15, -0.1, -0.82]).joint_trajectory
    return _valid_trajectory.cached


@settings(max_examples=CHEAP)
@given(field=st.sampled_from(['time_from_start', 'positions', 'velocities', 'accelerations']),
       row=st.integers(0, 1000), column=st.integers(0, 2), value=hostile_floats)
def test_validate_jtc_rejects_any_corrupted_point_by_name(field, row, column, value):
    trajectory = _valid_trajectory()
    arrays = {name: np.array(getattr(trajectory, name)) for name in
              ('time_from_start', 'positions', 'velocities', 'accelerations')}
    array = arrays[field]
    row %= array.shape[0]
    if array.ndim == 1:
        array[row] = value
    else:
        array[row, column] = value
    try:
        corrupted = JointTrajectoryData(trajectory.joint_names, **arrays)
        validate_jtc(corrupted, expect_names=trajectory.joint_names)
    except InvalidInputError as error:
        _assert_names(error, field)
        return
    # Accepted: then it still is a trajectory JTC takes and that stops at its end.
    times = corrupted.time_from_start
    assert times[0] >= 0.0 and (np.diff(np.round(times * 1e9)) > 0).all()
    for array in (corrupted.positions, corrupted.velocities, corrupted.accelerations):
        assert np.isfinite(array).all()
    assert np.abs(corrupted.velocities[-1]).max() < REST_TOLERANCE
    assert np.abs(corrupted.accelerations[-1]).max() < REST_TOLERANCE


@settings(max_examples=CHEAP)
@given(names=st.one_of(st.lists(st.text(max_size=3), max_size=4), non_numbers))
def test_validate_jtc_rejects_bad_joint_names_by_name(names):
    trajectory = _valid_trajectory()
    try:
        validate_jtc(JointTrajectoryData(names, trajectory.time_from_start, trajectory.positions,
                                         trajectory.velocities, trajectory.accelerations),
                     expect_names=trajectory.joint_names)
    except InvalidInputError as error:
        _assert_names(error, 'joint_names')
        return
    assert tuple(names) == trajectory.joint_names


# --- parameter sets ------------------------------------------------------------------------

NODE_NAMES = sorted(set(default_values()) - set(CORE_NAMES))


def _plausible(name):
    """Return values for parameter ``name``: around its default, hostile, or of a wrong type."""
    default = default_values()[name]
    if isinstance(default, float):
        around = (st.floats(min(default * 0.5, default * 2.0), max(default * 0.5, default * 2.0))
                  if default else st.floats(-1.0, 1.0))
        return st.one_of(around, hostile_floats, non_numbers)
    if isinstance(default, list):
        return st.one_of(st.lists(hostile_floats, max_size=7), non_numbers,
                         st.lists(st.text(max_size=4), max_size=4))
    if isinstance(default, int):
        return st.one_of(st.integers(-5, 2000), hostile_floats, non_numbers)
    return st.one_of(st.just(default), st.text(max_size=12), non_numbers)


# A change of the key may be reported under these names: values checked against each other.
RELATED = {'joint_min': ('joint_max',), 'joint_max': ('joint_min',),
           'base_radius': ('forearm',), 'effector_radius': ('forearm',),
           'workspace_z_min': ('workspace_z_max',), 'workspace_z_max': ('workspace_z_min',)}


def _named_by(changes):
    """Return the names an error about ``changes`` may carry."""
    return [*changes, *(name for key in changes for name in RELATED.get(key, ()))]


@st.composite
def parameter_changes(draw, names):
    """Draw a few parameters of ``names`` and a value for each."""
    chosen = draw(st.lists(st.sampled_from(names), min_size=1, max_size=4, unique=True))
    return {name: draw(_plausible(name)) for name in chosen}


@settings(max_examples=MEDIUM)
@given(changes=parameter_changes(sorted(CORE_NAMES)))
def test_planner_config_from_flat_is_valid_or_names_a_changed_parameter(changes):
    try:
        config = PlannerConfig.from_flat(changes)
    except EllipathError as error:
        _assert_names(error, *_named_by(changes))
        return
    assert isinstance(config, PlannerConfig)


@settings(max_examples=MEDIUM)
@given(changes=parameter_changes(sorted(CORE_NAMES) + NODE_NAMES))
def test_build_settings_is_valid_or_names_a_changed_parameter(changes):
    try:
        result = build_settings({**default_values(), **changes})
    except EllipathError as error:
        _assert_names(error, *_named_by(changes))
        return
    assert result.planner.joint_names == tuple(result.planner.joint_names)


# --- planning ------------------------------------------------------------------------------

def assert_executable(trajectory, config):
    """Assert that JTC takes ``trajectory``, within every limit as executed; return the TCP."""
    validate_jtc(trajectory, expect_names=config.joint_names)
    check_joint_limits(trajectory, config.geometry, config.joint_limits,
                       samples_per_segment=_QUINTIC_CHECK_SAMPLES)
    times = trajectory.time_from_start
    t = np.linspace(times[0], times[-1], max(int((times[-1] - times[0]) / 2e-4), 2))
    tcp = forward_kinematics(quintic_positions(trajectory, t), config.geometry)
    # The planner checks the executed motion every _WORKSPACE_CHECK_PERIOD, allowing
    # _EXECUTED_WORKSPACE_TOLERANCE; in between, the TCP (whose executed speed the planner
    # keeps within max_speed) moves up to half a period's travel further: the documented bound.
    margin = (_EXECUTED_WORKSPACE_TOLERANCE
              + config.limits.max_speed * _WORKSPACE_CHECK_PERIOD / 2.0)
    assert config.workspace.contains(tcp, tolerance=margin).all()
    return tcp


def _assert_safe(trajectory, start, place, config):
    """Assert that ``trajectory`` is one JTC takes, within every limit, start to place."""
    tcp = assert_executable(trajectory, config)
    np.testing.assert_allclose(tcp[0], start, atol=END_TOLERANCE)
    np.testing.assert_allclose(tcp[-1], place, atol=END_TOLERANCE)


# Degenerate pairs: the same point, vertical moves, offsets of a millimetre and less.
offsets = st.sampled_from([0.0, 1e-9, 1e-6, 1e-4, 0.001, 0.0011, 0.002, 0.01, 0.1])


@st.composite
def degenerate_pairs(draw):
    """Draw (pick, place) a tiny or vertical move apart."""
    pick = draw(points)
    direction = draw(st.sampled_from([(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0),
                                      (0.0, 0.0, -1.0), (0.6, 0.8, 0.0), (0.6, 0.0, 0.8)]))
    return pick, pick + draw(offsets) * np.array(direction)


@settings(max_examples=PLANS)
@given(start=st.one_of(st.just(HOME), points), pair=st.one_of(
    st.tuples(points, points), degenerate_pairs()),
    pick_dwell=st.sampled_from([0.0, 0.0, 0.1, 1e-9, 1e-79]),
    place_dwell=st.sampled_from([0.0, 0.05, 4e-10]))
def test_plan_cycle_is_safe_or_rejected_with_a_reason(start, pair, pick_dwell, place_dwell):
    pick, place = pair
    config = PlannerConfig()
    try:
        plan = plan_cycle(start, pick, place, config, pick_dwell, place_dwell)
    except EllipathError as error:
        assert ': expected ' in str(error), str(error)
        event(f'rejected: {error.kind}')
        return
    event('planned')
    _assert_safe(plan.joint_trajectory, start, place, config)


def _finite_point(value):
    """Tell whether ``value`` is 3 finite numbers."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return array.shape == (3,) and bool(np.isfinite(array).all())


@settings(max_examples=MEDIUM)
@given(start=st.one_of(st.lists(hostile_floats, max_size=4), non_numbers),
       pick=st.one_of(points, st.lists(hostile_floats, min_size=3, max_size=3)),
       place=st.one_of(points, st.lists(hostile_floats, min_size=3, max_size=3)),
       dwell=hostile_floats)
def test_plan_cycle_names_a_hostile_input(start, pick, place, dwell):
    assume(not (_finite_point(start) and _finite_point(pick) and _finite_point(place)
                and math.isfinite(dwell) and 0.0 <= dwell <= 10.0))
    try:
        plan_cycle(start, pick, place, PlannerConfig(), dwell, 0.0)
    except EllipathError as error:
        _assert_names(error, 'start', 'pick', 'place', 'pick_dwell')
        return
    raise AssertionError('a hostile input was planned')


@settings(max_examples=PLANS)
@given(pair=st.one_of(st.tuples(points, points), degenerate_pairs()),
       clearances=st.tuples(st.sampled_from([0.0, 1e-6, 0.001, 0.025, 0.1]),
                            st.sampled_from([0.0, 0.025, 0.3])))
def test_plan_transfer_is_safe_or_rejected_with_a_reason(pair, clearances):
    pick, place = pair
    config = PlannerConfig()
    try:
        leg = plan_transfer(pick, place, config, pick_clearance=clearances[0],
                            place_clearance=clearances[1])
    except EllipathError as error:
        assert ': expected ' in str(error), str(error)
        event(f'rejected: {error.kind}')
        return
    event('planned')
    _assert_safe(leg.joint_trajectory, pick, place, config)


@st.composite
def configurations(draw):
    """Draw a valid configuration: limits, arc policy, profile, output and workspace."""
    flat = {
        # Slow limits make long plans (seconds each): the budget keeps them moderate.
        'max_speed': draw(st.floats(0.5, 8.0)),
        'max_accel': draw(st.floats(10.0, 150.0)),
        'max_jerk': draw(st.floats(1000.0, 20000.0)),
        'max_accel_jump': draw(st.floats(0.0, 60.0)),
        'max_joint_velocity': draw(st.floats(2.0, 30.0)),
        'max_joint_accel': draw(st.floats(20.0, 800.0)),
        'pick_clearance': draw(st.sampled_from([0.0, 0.01, 0.025, 0.05])),
        'place_clearance': draw(st.sampled_from([0.0, 0.01, 0.025, 0.05])),
        'arc_policy': draw(st.sampled_from(['paper', 'apex_clearance', 'min_radius'])),
        'apex_clearance': draw(st.floats(0.001, 0.1)),
        'min_radius': draw(st.floats(0.001, 0.1)),
        'profile': draw(st.sampled_from(['time_optimal', 'curvature'])),
        'join': draw(st.sampled_from(['g2', 'paper'])),
        'join_tolerance': draw(st.sampled_from([1e-4, 5e-4, 2e-3])),
        'output_mode': draw(st.sampled_from(['knots', 'samples'])),
        'knot_tolerance': draw(st.sampled_from([1e-5, 1e-4, 1e-3])),
        'sample_period': draw(st.sampled_from([0.002, 0.004, 0.01])),
        'keep_out_boxes': draw(st.sampled_from([[], [-0.05, -0.05, -1.0, 0.05, 0.05, -0.9]])),
    }
    if flat['profile'] == 'curvature':
        flat['join'] = 'paper'  # the paper's node rule is defined on the paper's path only
    return PlannerConfig.from_flat(flat)


@settings(max_examples=CONFIG_PLANS)
@given(config=configurations(), pick=inside, place=inside)
def test_any_valid_configuration_plans_safely_or_says_why(config, pick, place):
    try:
        plan = plan_cycle(HOME, pick, place, config)
    except EllipathError as error:
        assert ': expected ' in str(error), str(error)
        event(f'rejected: {error.kind}')
        return
    event('planned')
    _assert_safe(plan.joint_trajectory, HOME, place, config)
