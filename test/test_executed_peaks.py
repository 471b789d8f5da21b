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

"""The executed peaks are the maxima of JTC's quintic, not of samples: against dense NumPy."""

from ellipath_ros.core import joint_trajectory, kinematics
from ellipath_ros.core.errors import UnreachableError
from ellipath_ros.core.joint_trajectory import (
    _EXECUTED_REFINE_SHARE, _joint_extremes, _quadratic_roots, DEFAULT_JOINT_NAMES,
    evaluate_segments, executed_table, JointTrajectoryData, segment_polynomials)
from ellipath_ros.core.kinematics import inverse_kinematics, tcp_derivatives
from ellipath_ros.core.knots import minimal_knots
from ellipath_ros.core.planner import plan_transfer, PlannerConfig
import numpy as np
import pytest

CONFIG = PlannerConfig()
# Evaluations per segment of the dense reference: its maxima are within ~1e-9 of the true.
DENSE = 20001


def dense_table(trajectory):
    """Return each segment's peaks (S, 5) from DENSE exact evaluations (NumPy, FK rates)."""
    coefficients = segment_polynomials(trajectory)
    lengths = np.diff(trajectory.time_from_start)
    offsets = lengths[:, None] * np.linspace(0.0, 1.0, DENSE)
    q, qdot, qddot, qdddot = evaluate_segments(coefficients, offsets)
    _, velocity, acceleration, jerk = tcp_derivatives(
        *(value.reshape(-1, 3) for value in (q, qdot, qddot, qdddot)), CONFIG.geometry)
    columns = [np.linalg.norm(value, axis=1) for value in (velocity, acceleration, jerk)]
    columns += [np.abs(qdot).max(axis=2).ravel(), np.abs(qddot).max(axis=2).ravel()]
    return np.stack([column.reshape(lengths.size, DENSE).max(axis=1) for column in columns],
                    axis=1)


def leg_knots(join):
    """Return the fewest knots of the paper's example (no points at the jerk steps)."""
    leg = plan_transfer([0.0, 0.0, -0.8], [0.3, 0.0, -0.75],
                        PlannerConfig.from_flat({'join': join}))
    return minimal_knots(leg.motion, CONFIG.geometry, tolerance=CONFIG.knot_tolerance)[0]


@pytest.mark.parametrize('join', ['g2', 'paper'])
def test_executed_table_finds_each_quantitys_maximum(join):
    knots = leg_knots(join)
    reported, dense = executed_table(knots, CONFIG.geometry), dense_table(knots)
    # Every value is the quantity at some instant: never above its maximum...
    assert (reported <= dense * (1.0 + 1e-6)).all()
    # ... the trajectory's peaks are the maxima (the samples alone are not) ...
    assert reported.max(axis=0) == pytest.approx(dense.max(axis=0), rel=1e-6)
    # ... the joint peaks are exact in every segment, and no segment's TCP peak is
    # missed by as much as the share that decides which segments are searched.
    assert reported[:, 3:] == pytest.approx(dense[:, 3:], rel=1e-7)
    assert (reported[:, 3:] >= dense[:, 3:] * (1.0 - 1e-12)).all()
    assert (reported[:, :3] >= (1.0 - _EXECUTED_REFINE_SHARE / 4.0) * dense[:, :3]).all()


def test_joint_extremes_are_the_maxima_of_random_quintics():
    rng = np.random.default_rng(5)
    for _ in range(50):
        coefficients = rng.normal(size=(6, 3)) * np.array([1, 2, 20, 200, 2e3, 2e4])[:, None]
        length = rng.uniform(0.005, 0.2)
        offsets = np.linspace(0.0, length, 200001)[None, :]
        _, qdot, qddot, _ = evaluate_segments(coefficients[None], offsets)
        speed, accel = _joint_extremes(coefficients, length)
        assert speed == pytest.approx(np.abs(qdot).max(), rel=1e-9)
        assert accel == pytest.approx(np.abs(qddot).max(), rel=1e-9)
        assert speed >= np.abs(qdot).max() * (1.0 - 1e-15)


@pytest.mark.parametrize('a, b, c, roots', [
    (1.0, -3.0, 2.0, (1.0, 2.0)),  # two roots
    (2.0, 0.0, -8.0, (-2.0, 2.0)),  # symmetric
    (1.0, 1.0, 1.0, (np.inf, np.inf)),  # none
    (0.0, 4.0, -2.0, (0.5, np.inf)),  # linear
    (0.0, 0.0, 1.0, (np.inf, np.inf)),  # constant
    (1e-12, 1.0, -1.0, (-1e12, 1.0)),  # nearly linear: no cancellation in the small root
])
def test_quadratic_roots(a, b, c, roots):
    assert _quadratic_roots(a, b, c) == pytest.approx(roots, rel=1e-9)
    assert _quadratic_roots.py_func(a, b, c) == pytest.approx(roots, rel=1e-9)


def test_a_quintic_through_an_unassembled_pose_is_named():
    q = inverse_kinematics(np.array([[0.0, 0.0, -0.8], [0.1, 0.0, -0.8]]), CONFIG.geometry)
    # Joint 0 swings far up between the two knots: the forearms cannot meet there.
    velocities = np.array([[200.0, 0.0, 0.0], [-200.0, 0.0, 0.0]])
    knots = JointTrajectoryData(DEFAULT_JOINT_NAMES, np.array([0.0, 0.1]), q, velocities,
                                np.zeros((2, 3)))
    with pytest.raises(UnreachableError, match='interpolated q'):
        executed_table(knots, CONFIG.geometry)


# The steps the executed-peak kernel takes per sample and per search step, inlined into the
# loops that call them: a call to a compiled step that takes arrays counts their references
# up and down (atomic), which cost ~40 % of _peak_rows' time on the bench's slowest requests.
PER_SAMPLE_STEPS = (joint_trajectory._polynomial, joint_trajectory._executed_tcp,
                    joint_trajectory._executed_value, kinematics._tcp_state,
                    kinematics._forward_point)


@pytest.mark.parametrize('step', PER_SAMPLE_STEPS, ids=lambda step: step.__name__)
def test_the_per_sample_steps_are_inlined(step):
    assert step.targetoptions['inline'] == 'always'


def test_the_inlined_peak_kernel_equals_its_steps_called_one_by_one():
    # The kernel's Python body, interpreted, calls each step as its own compiled function
    # (as before they were inlined): the same table and the same failed segment, bit for bit.
    leg = plan_transfer([0.05, -0.1, -0.85], [-0.25, 0.15, -0.7], CONFIG)
    trajectory = leg.joint_trajectory
    times = trajectory.time_from_start
    todo = np.ones(times.size - 1, bool)
    todo[::3] = False
    tables = []
    for kernel in (joint_trajectory._peak_rows, joint_trajectory._peak_rows.py_func):
        table = np.zeros((times.size - 1, 5))
        table[~todo] = 1.0  # rows taken from earlier knots: kept, and searched if near a peak
        failed_offset = np.zeros(1)
        failed = kernel(times, trajectory.positions, trajectory.velocities,
                        trajectory.accelerations, todo, 12, _EXECUTED_REFINE_SHARE,
                        *kinematics._kernel_geometry(CONFIG.geometry), table, failed_offset)
        tables.append((failed, table, failed_offset))
    (failed, table, _), (failed_steps, table_steps, _) = tables
    assert failed == failed_steps == -1
    assert table.tobytes() == table_steps.tobytes()
