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

"""The executed workspace check, skipping what clearances cover, finds the first sample outside."""

import dataclasses

from ellipath_ros.core.joint_trajectory import executed_table, quintic_positions
from ellipath_ros.core.kinematics import _kernel_geometry, forward_kinematics
from ellipath_ros.core.planner import (
    _EXECUTED_WORKSPACE_TOLERANCE, _first_outside, _WORKSPACE_CHECK_PERIOD,
    _WORKSPACE_SPEED_MARGIN, plan_transfer, PlannerConfig)
from ellipath_ros.core.workspace import clearance, inside, SafeWorkspace
import numpy as np

CONFIG = PlannerConfig()


def first_outside(leg, workspace, speed_bounds):
    """Return the planner's first sample outside ``workspace``, the expected one and the TCP."""
    trajectory = leg.joint_trajectory
    times = trajectory.time_from_start
    count = int(np.ceil((times[-1] - times[0]) / _WORKSPACE_CHECK_PERIOD)) + 1
    found = _first_outside(times, trajectory.positions, trajectory.velocities,
                           trajectory.accelerations, count, speed_bounds,
                           *_kernel_geometry(CONFIG.geometry)[:5], workspace.radius,
                           workspace.z_min, workspace.z_max, workspace.box_table(),
                           _EXECUTED_WORKSPACE_TOLERANCE)
    # The independent answer: every sample, by NumPy's forward kinematics.
    t = np.linspace(times[0], times[-1], count)
    tcp = forward_kinematics(quintic_positions(trajectory, t), CONFIG.geometry)
    inside_rows = workspace.contains(tcp, tolerance=_EXECUTED_WORKSPACE_TOLERANCE)
    expected = -1 if inside_rows.all() else int(np.argmin(inside_rows))
    return found, expected, tcp


def test_skipping_finds_the_first_sample_outside_as_every_sample_does():
    rng = np.random.default_rng(3)
    leg = plan_transfer([0.0, 0.0, -0.8], [0.3, 0.0, -0.75], CONFIG)
    segments = leg.joint_trajectory.time_from_start.size - 1
    # The planner's bounds (each segment's executed peak speed), one for the whole leg, none.
    executed = _WORKSPACE_SPEED_MARGIN * leg.executed['peak_speed']
    every_sample = np.full(segments, np.inf)
    _, _, tcp = first_outside(leg, CONFIG.workspace, every_sample)
    rejected = 0
    for _ in range(60):
        # A small keep-out box near a random point of the path, a radius or a floor that
        # the path touches: the path grazes a bound, crosses it, or stays clear of it.
        centre = tcp[rng.integers(tcp.shape[0])] + rng.normal(scale=0.003, size=3)
        size = rng.uniform(0.0005, 0.01, 3)
        radius = np.hypot(tcp[:, 0], tcp[:, 1]).max() + rng.normal(scale=0.0005)
        floor = tcp[:, 2].min() + rng.normal(scale=0.0005)
        workspace = dataclasses.replace(
            CONFIG.workspace, keep_out_boxes=(tuple(centre - size) + tuple(centre + size),),
            radius=radius if rng.random() < 0.3 else CONFIG.workspace.radius,
            z_min=floor if rng.random() < 0.3 else CONFIG.workspace.z_min)
        assert isinstance(workspace, SafeWorkspace)
        found, expected, _ = first_outside(leg, workspace, every_sample)
        assert found == expected
        for bounds in (_segment_speed_bounds(leg), np.full(segments, executed)):
            assert first_outside(leg, workspace, bounds)[0] == expected
        rejected += expected >= 0
    # Both outcomes were tried.
    assert 10 < rejected < 55


def _segment_speed_bounds(leg):
    """Return the planner's speed bound of each segment: its executed peak, with the margin."""
    table = executed_table(leg.joint_trajectory, CONFIG.geometry)
    return _WORKSPACE_SPEED_MARGIN * table[:, 0]


def test_a_point_moved_by_its_clearance_stays_inside():
    rng = np.random.default_rng(5)
    tolerance = _EXECUTED_WORKSPACE_TOLERANCE
    tried = 0
    for boxes in ((), (0.05, -0.1, -0.9, 0.2, 0.1, -0.7)):
        workspace = SafeWorkspace(keep_out_boxes=boxes)
        bounds = (workspace.radius, workspace.z_min, workspace.z_max, workspace.box_table(),
                  tolerance)
        for _ in range(2000):
            point = rng.uniform([-0.41, -0.41, -1.01], [0.41, 0.41, -0.54])
            if not inside(*point, *bounds):
                continue
            tried += 1
            distance = clearance(*point, *bounds)
            direction = rng.normal(size=3)
            moved = point + 0.999 * distance * direction / np.linalg.norm(direction)
            assert inside(*moved, *bounds)
            if boxes:
                continue
            # The cylinder's clearance is its distance: a millimetre more, up, down or away
            # from the z axis, leaves it.
            outward = np.array([point[0], point[1], 0.0]) / np.hypot(point[0], point[1])
            beyond = point + (distance + 1e-3) * np.vstack(([0, 0, 1], [0, 0, -1], outward))
            assert not all(inside(*row, *bounds) for row in beyond)
    assert tried > 1000
