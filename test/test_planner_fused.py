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

"""The planner's and kinematics' shortcuts give what the steps they stand for give."""

import dataclasses

from ellipath_ros.core import planner
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.kinematics import DeltaGeometry
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.kinematics import joint_motion
from ellipath_ros.core.kinematics import joint_speed_caps
from ellipath_ros.core.kinematics import joint_trig_motion
from ellipath_ros.core.kinematics import joint_trig_peaks
from ellipath_ros.core.workspace import SafeWorkspace
import numpy as np
import pytest

CONFIG = planner.PlannerConfig()
HOME = np.array([0.0, 0.0, -0.8])
PICK = np.array([-0.15, 0.1, -0.85])
PLACE = np.array([0.15, 0.05, -0.8])


def _message(call):
    """Return the type and message of the error ``call`` raises."""
    with pytest.raises(EllipathError) as caught:
        call()
    return type(caught.value), str(caught.value)


def _ends_step_by_step(pick, place, config):
    """Check pick and place as plan_transfer checked them one call after the other."""
    inverse_kinematics(planner.require_coordinates('pick', pick), config.geometry, name='pick')
    inverse_kinematics(planner.require_coordinates('place', place), config.geometry,
                       name='place')
    config.workspace.check(pick, name='pick')
    config.workspace.check(place, name='place')


@pytest.mark.parametrize('pick, place', [
    ([0.0, 0.0, 0.1], [0.0, 0.0, -0.8]),          # the pick above the base
    ([0.0, 0.0, -1.5], [0.0, 0.0, 0.2]),          # both out of reach: the pick first
    ([0.0, 0.0, -1.5], [0.0, float('nan'), -0.8]),  # a bad place after an unreachable pick
    ([0.0, 0.0, -0.8], [0.0, float('nan'), -0.8]),
    ([0.0, 0.0, -0.8], [20.0, 0.0, -0.8]),
    ([0.0, 0.0, -0.8], [0.5, 0.0, -0.5]),        # beyond a joint limit
    ([0.0, 0.0, -0.8], [0.1, 0.1, -0.5]),        # reachable, above the workspace
    ([0.45, 0.0, -0.8], [0.1, 0.1, -0.5]),       # both outside: the pick first
    ([0.1, 0.0, -0.8], [0.0, 0.1, -0.7]),        # inside the keep-out box
    ('pick', [0.0, 0.0, -0.8]),
])
def test_the_ends_are_named_in_the_order_of_their_checks(pick, place):
    config = dataclasses.replace(CONFIG, workspace=SafeWorkspace(
        keep_out_boxes=(-0.05, 0.05, -0.75, 0.05, 0.15, -0.65)))
    expected = _message(lambda: _ends_step_by_step(pick, place, config))
    assert _message(lambda: planner._check_ends(pick, place, config)) == expected


def test_ends_within_reach_and_workspace_pass():
    assert planner._check_ends(PICK, PLACE, CONFIG) is None
    assert planner._check_ends(list(PICK), tuple(PLACE), CONFIG) is None


def test_speed_caps_of_coordinate_rows_are_those_of_points():
    rng = np.random.default_rng(3)
    points = np.column_stack((rng.uniform(-0.3, 0.3, (50, 2)), rng.uniform(-0.95, -0.6, 50)))
    directions = rng.normal(size=(50, 3))
    caps = joint_speed_caps(points, directions, CONFIG.geometry, 5.0)
    assert caps is not None
    rows = joint_speed_caps(np.ascontiguousarray(points.T), np.ascontiguousarray(directions.T),
                            CONFIG.geometry, 5.0, rows=True, extra=HOME)
    assert rows.tobytes() == caps.tobytes()
    # The extra point has no cap, but must be reachable.
    assert joint_speed_caps(points, directions, CONFIG.geometry, 5.0,
                            extra=[0.0, 0.0, -1.5]) is None


def test_joint_peaks_come_with_the_joint_states():
    rng = np.random.default_rng(5)
    points = np.column_stack((rng.uniform(-0.3, 0.3, (400, 2)), rng.uniform(-0.95, -0.6, 400)))
    velocities, accelerations = 2.0 * rng.normal(size=(400, 3)), 40.0 * rng.normal(size=(400, 3))
    *states, peak_velocity, peak_accel = joint_trig_peaks(points, velocities, accelerations,
                                                          CONFIG.geometry)
    for state, expected in zip(states, joint_trig_motion(points.tolist(), velocities,
                                                         accelerations, CONFIG.geometry)):
        assert state.tobytes() == expected.tobytes()
    _, qdot, qddot = joint_motion(points, velocities, accelerations, CONFIG.geometry)
    assert (peak_velocity, peak_accel) == (np.abs(qdot).max(), np.abs(qddot).max())


@pytest.mark.parametrize('where', ['points', 'velocities', 'accelerations'])
def test_joint_states_of_a_non_finite_row_are_refused_as_the_checks_name_it(where):
    # Row 1 is out of reach, row 2 not finite: every array is checked before any row.
    arrays = {'points': np.array([[0.0, 0.0, -0.8], [5.0, 0.0, -0.8], [0.1, 0.0, -0.8]]),
              'velocities': np.ones((3, 3)), 'accelerations': np.ones((3, 3))}
    arrays[where][2] = [0.0, np.inf, 0.0]
    expected = _message(lambda: joint_trig_motion(
        *(value.tolist() for value in arrays.values()), CONFIG.geometry))
    assert expected[1].startswith(f'{where}[2]: expected finite values')
    assert _message(lambda: joint_trig_peaks(*arrays.values(), CONFIG.geometry)) == expected


def test_a_joint_limit_names_the_angle_beyond_it():
    point = np.array([0.0, 0.0, -0.6])
    q = inverse_kinematics(point, DeltaGeometry())
    geometry = DeltaGeometry(joint_min=q[0] + 0.05, joint_max=q[0] + 1.0)
    with pytest.raises(EllipathError, match=f'arm 0 needs q={q[0]:.6g} rad'):
        inverse_kinematics(point, geometry)
