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

"""The safe workspace: the cylinder, keep-out boxes, messages, and the planner's check."""

import math
import re

from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import WorkspaceError
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.joint_trajectory import quintic_positions
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import reachable
from ellipath_ros.core.planner import _EXECUTED_WORKSPACE_TOLERANCE
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.settings import default_values
from ellipath_ros.core.workspace import boxes_from_flat
from ellipath_ros.core.workspace import SafeWorkspace
import numpy as np
import pytest

HOME = np.array([0.0, 0.0, -0.8])
# A box standing between x = -0.02 and 0.02 m across the whole workspace in y.
WALL_X = (-0.02, 0.02)


def _config(**flat):
    """Return the default planner config with some flat parameters changed."""
    return PlannerConfig.from_flat(flat)


def _executed_tcp(trajectory, geometry, period=1e-5):
    """Return (t, TCP) of JTC's quintic through ``trajectory``, densely, via FK."""
    times = trajectory.time_from_start
    t = np.arange(times[0], times[-1], period)
    q, _, _ = quintic_interpolate(trajectory, t)
    return t, forward_kinematics(q, geometry)


def test_the_default_cylinder_lies_inside_the_reach_of_the_default_robot():
    workspace = SafeWorkspace()
    angle, height = np.meshgrid(np.linspace(0.0, 2.0 * np.pi, 73),
                                np.linspace(workspace.z_min, workspace.z_max, 46))
    for radius in (0.0, 0.5 * workspace.radius, workspace.radius):
        points = np.stack([radius * np.cos(angle).ravel(), radius * np.sin(angle).ravel(),
                           height.ravel()], axis=1)
        assert reachable(points, PlannerConfig().geometry).all(), radius


@pytest.mark.parametrize('point, inside', [
    ([0.0, 0.0, -0.8], True),
    ([0.4, 0.0, -0.8], True),  # on the cylinder: allowed
    ([0.0, 0.0, -1.0], True),
    ([0.0, 0.0, -0.55], True),
    ([0.3, 0.3, -0.8], False),  # r = 0.424 m
    ([0.0, 0.0, -0.5499], False),
    ([0.0, 0.0, -1.0001], False),
    ([math.nan, 0.0, -0.8], False),
    ([0.0, math.inf, -0.8], False),
])
def test_cylinder_membership(point, inside):
    assert SafeWorkspace().contains(point) == inside


def test_keep_out_boxes_exclude_their_inside_but_not_their_faces():
    workspace = SafeWorkspace(keep_out_boxes=[-0.1, -0.1, -1.0, 0.1, 0.1, -0.9,
                                              0.2, 0.2, -0.7, 0.3, 0.3, -0.6])
    points = np.array([
        [0.0, 0.0, -0.95],  # inside box 0
        [0.0, 0.0, -0.9],  # on the top face of box 0
        [0.1, 0.0, -0.95],  # on a side face of box 0
        [0.25, 0.25, -0.65],  # inside box 1
        [0.0, 0.0, -0.85],  # above box 0
    ])
    assert workspace.contains(points).tolist() == [False, True, True, False, True]
    assert workspace.keep_out_boxes == ((-0.1, -0.1, -1.0, 0.1, 0.1, -0.9),
                                        (0.2, 0.2, -0.7, 0.3, 0.3, -0.6))


def test_the_message_names_the_point_its_time_and_the_bound():
    workspace = SafeWorkspace()
    points = np.array([[0.0, 0.0, -0.8], [0.1, 0.0, -0.6], [0.2, 0.0, -0.52], [0.3, 0.0, -0.5]])
    with pytest.raises(WorkspaceError) as caught:
        workspace.check(points, name='tcp', times=[0.0, 0.1, 0.2, 0.3])
    message = str(caught.value)
    assert message.startswith('tcp[2] at t = 0.2000 s: expected a point within the safe '
                              'workspace (r <= 0.4 m from the z axis, z in [-1, -0.55] m), '
                              'got (0.2, 0, -0.52) m: above workspace_z_max = -0.55 m by 0.03')
    assert caught.value.index == 2 and caught.value.time == pytest.approx(0.2)
    assert caught.value.kind == 'workspace'
    assert isinstance(caught.value, EllipathError)


@pytest.mark.parametrize('point, reason', [
    ([0.0, 0.0, -1.2], r'below workspace_z_min = -1 m by 0\.2'),
    ([0.35, 0.35, -0.8], r'0\.494975 m from the z axis, beyond workspace_radius = 0\.4 m'),
    ([0.0, 0.0, -0.95], r'inside keep_out_boxes\[0\] = \[-0\.1, -0\.1, -1\.0, 0\.1, 0\.1, '
                        r'-0\.9\] m'),
])
def test_each_bound_is_named(point, reason):
    workspace = SafeWorkspace(keep_out_boxes=[-0.1, -0.1, -1.0, 0.1, 0.1, -0.9])
    with pytest.raises(WorkspaceError, match=r'^place: expected .*' + reason):
        workspace.check(point, name='place')


@pytest.mark.parametrize('values, message', [
    ({'radius': 0.0}, r'workspace_radius: expected a value in \[0\.001, 10\] m, got 0\.0'),
    ({'radius': math.nan}, 'workspace_radius: expected a finite number, got nan'),
    ({'z_min': -math.inf}, 'workspace_z_min: expected a finite number, got -inf'),
    ({'z_max': 11.0}, r'workspace_z_max: expected a value in \[-10, 10\] m, got 11\.0'),
    ({'z_min': -0.5, 'z_max': -0.6}, 'workspace_z_max: expected a value > workspace_z_min'),
    ({'keep_out_boxes': [0.0] * 5}, 'keep_out_boxes: expected a multiple of 6 values'),
    ({'keep_out_boxes': [0.0] * 7}, 'got 7 values'),
    ({'keep_out_boxes': [0.0, 0.0, 0.0, 0.1, 0.1, math.nan]},
     r'keep_out_boxes\[5\]: expected a finite number, got nan'),
    ({'keep_out_boxes': [0.0, 0.0, 0.0, 0.1, 0.1, 'x']},
     r"keep_out_boxes\[5\]: expected a number, got 'x'"),
    ({'keep_out_boxes': [0.0, 0.0, 0.0, 0.1, 0.1, True]},
     r'keep_out_boxes\[5\]: expected a number, got True'),
    ({'keep_out_boxes': [0.0, 0.0, 0.0, 0.1, 0.0, 0.1]},
     r'keep_out_boxes\[0\]: expected ymin < ymax, got 0 and 0 m'),
    ({'keep_out_boxes': 'box'}, 'keep_out_boxes: expected a flat list of 6 numbers per box'),
])
def test_invalid_workspaces_are_rejected_naming_the_value(values, message):
    with pytest.raises(InvalidInputError, match=message):
        SafeWorkspace(**values)


def test_boxes_flat_or_grouped_are_the_same_and_none_is_empty():
    flat = [0.0, 0.0, -1.0, 0.1, 0.1, -0.9, 0.2, 0.2, -1.0, 0.3, 0.3, -0.9]
    assert boxes_from_flat(flat) == boxes_from_flat([flat[:6], flat[6:]])
    assert boxes_from_flat(None) == boxes_from_flat([]) == ()


def test_the_planner_config_takes_the_flat_parameters():
    assert default_values()['keep_out_boxes'] == []
    config = _config(workspace_radius=0.3, workspace_z_min=-0.9, workspace_z_max=-0.6,
                     keep_out_boxes=[0.0, 0.0, -0.9, 0.1, 0.1, -0.8])
    assert config.workspace == SafeWorkspace(0.3, -0.9, -0.6, ((0.0, 0.0, -0.9, 0.1, 0.1, -0.8),))
    with pytest.raises(InvalidInputError, match='keep_out_boxes'):
        _config(keep_out_boxes=[0.0, 0.0, -0.9])


@pytest.mark.parametrize('name, pick, place, start', [
    ('pick', [0.0, 0.0, -0.5], [0.1, 0.0, -0.8], HOME),
    ('place', [0.1, 0.0, -0.8], [0.3, 0.3, -0.8], HOME),
    ('start', [0.1, 0.0, -0.8], [-0.1, 0.0, -0.8], [0.0, 0.0, -1.05]),
])
def test_pick_place_and_start_outside_are_named_before_any_motion(name, pick, place, start):
    with pytest.raises(WorkspaceError, match=rf'^{name}: expected a point within the safe'):
        plan_cycle(start, pick, place, _config())


def test_a_pick_inside_a_keep_out_box_is_named_as_the_pick():
    config = _config(keep_out_boxes=[0.05, -0.05, -0.9, 0.15, 0.05, -0.7])
    with pytest.raises(WorkspaceError, match=r'^pick: .*inside keep_out_boxes\[0\]'):
        plan_cycle(HOME, [0.1, 0.0, -0.8], [-0.1, 0.0, -0.8], config)


def test_an_arc_whose_apex_pierces_the_top_is_rejected_at_the_first_point_above():
    # Lift to z = -0.575 m, apex 30 mm higher: 5 mm above the default top, -0.55 m.
    pick, place = [0.1, 0.0, -0.6], [-0.1, 0.0, -0.6]
    arc = {'arc_policy': 'apex_clearance', 'apex_clearance': 0.03}
    loose = plan_cycle(pick, pick, place, _config(workspace_z_max=-0.4, **arc))
    t, tcp = _executed_tcp(loose.joint_trajectory, _config().geometry)
    above = tcp[:, 2] > -0.55 + _EXECUTED_WORKSPACE_TOLERANCE
    assert above.any(), 'the test case must rise above the default top'
    first = t[np.argmax(above)]
    with pytest.raises(WorkspaceError) as caught:
        plan_cycle(pick, pick, place, _config(**arc))
    message = str(caught.value)
    assert re.match(r'^executed TCP of the transfer leg\[\d+\] at t = \d\.\d{4} s: expected a '
                    r'point within the safe workspace .* above workspace_z_max = -0\.55 m by ',
                    message), message
    # The same first crossing as the independent dense check, within the check's step.
    assert caught.value.time == pytest.approx(first, abs=1.5e-4)


def _wall_config(top):
    """Return the default config with a wall x in WALL_X, all y, from z = -1 m up to ``top``."""
    return _config(keep_out_boxes=[WALL_X[0], -0.5, -1.0, WALL_X[1], 0.5, top])


def test_a_keep_out_box_under_the_arc_is_cleared_and_one_in_its_way_is_named():
    pick, place = [0.15, 0.05, -0.9], [-0.15, -0.05, -0.9]
    free = plan_cycle(pick, pick, place, _config())
    t, tcp = _executed_tcp(free.joint_trajectory, _config().geometry)
    over_wall = (tcp[:, 0] > WALL_X[0]) & (tcp[:, 0] < WALL_X[1])
    lowest = tcp[over_wall, 2].min()
    # A wall 1 mm below the lowest point the arc passes over it: planned.
    plan_cycle(pick, pick, place, _wall_config(lowest - 0.001))
    # 2 mm above: the first point of the executed motion inside the wall is named.
    inside = over_wall & (tcp[:, 2] < lowest + 0.002 - _EXECUTED_WORKSPACE_TOLERANCE)
    with pytest.raises(WorkspaceError, match=r'^executed TCP of the transfer leg\[\d+\] at t = '
                                             r'.* inside keep_out_boxes\[0\]') as caught:
        plan_cycle(pick, pick, place, _wall_config(lowest + 0.002))
    assert caught.value.time == pytest.approx(t[np.argmax(inside)], abs=1.5e-4)


def test_the_approach_leg_is_checked_too():
    # From home over the wall onto a pick beyond it: the approach crosses the wall.
    config = _wall_config(-0.674)  # 2 mm above the lowest point of the approach over it
    with pytest.raises(WorkspaceError, match=r'^executed TCP of the approach leg\[\d+\]'):
        plan_cycle([0.15, 0.0, -0.85], [-0.15, 0.0, -0.85], [-0.2, 0.1, -0.85], config)


def test_a_cycle_on_the_boundary_is_planned_and_its_motion_stays_inside():
    # Pick and place on the bottom and the cylinder: the motion touches the workspace.
    config = _config()
    plan = plan_cycle(HOME, [0.4, 0.0, -1.0], [0.0, -0.4, -1.0], config)
    _, tcp = _executed_tcp(plan.joint_trajectory, config.geometry)
    assert config.workspace.contains(tcp, tolerance=_EXECUTED_WORKSPACE_TOLERANCE).all()


def test_quintic_positions_are_those_of_quintic_interpolate():
    plan = plan_cycle(HOME, [0.1, 0.05, -0.85], [-0.15, -0.1, -0.82], _config())
    trajectory = plan.joint_trajectory
    t = np.linspace(-0.1, trajectory.time_from_start[-1] + 0.1, 2001)
    np.testing.assert_array_equal(quintic_positions(trajectory, t),
                                  quintic_interpolate(trajectory, t)[0])
