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

"""The executed workspace check in blocks finds the first sample outside, as every sample does."""

import dataclasses

from ellipath_ros.core.joint_trajectory import quintic_positions
from ellipath_ros.core.kinematics import _kernel_geometry, forward_kinematics
from ellipath_ros.core.planner import (
    _EXECUTED_WORKSPACE_TOLERANCE, _first_outside, _WORKSPACE_CHECK_PERIOD,
    _WORKSPACE_CHECK_STRIDE, _WORKSPACE_COARSE_BLOCKS, _WORKSPACE_SPEED_MARGIN, plan_transfer,
    PlannerConfig)
from ellipath_ros.core.workspace import SafeWorkspace
import numpy as np

CONFIG = PlannerConfig()


def first_outside(leg, workspace, stride, coarse_blocks=1):
    """Return the planner's first sample outside ``workspace``, checked in blocks of stride."""
    trajectory = leg.joint_trajectory
    times = trajectory.time_from_start
    t = np.linspace(times[0], times[-1],
                    int(np.ceil((times[-1] - times[0]) / _WORKSPACE_CHECK_PERIOD)) + 1)
    margin = (_WORKSPACE_SPEED_MARGIN * leg.executed['peak_speed'] * stride * (t[1] - t[0])
              / 2.0)
    found = _first_outside(times, trajectory.positions, trajectory.velocities,
                           trajectory.accelerations, t, stride, coarse_blocks, margin,
                           *_kernel_geometry(CONFIG.geometry)[:5], workspace.radius,
                           workspace.z_min, workspace.z_max, workspace.box_table(),
                           _EXECUTED_WORKSPACE_TOLERANCE)
    # The independent answer: every sample, by NumPy's forward kinematics.
    tcp = forward_kinematics(quintic_positions(trajectory, t), CONFIG.geometry)
    inside = workspace.contains(tcp, tolerance=_EXECUTED_WORKSPACE_TOLERANCE)
    expected = -1 if inside.all() else int(np.argmin(inside))
    return found, expected, tcp


def test_blocks_find_the_first_sample_outside_as_every_sample_does():
    rng = np.random.default_rng(3)
    leg = plan_transfer([0.0, 0.0, -0.8], [0.3, 0.0, -0.75], CONFIG)
    _, _, tcp = first_outside(leg, CONFIG.workspace, 1)
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
        found, expected, _ = first_outside(leg, workspace, _WORKSPACE_CHECK_STRIDE)
        assert found == expected
        assert first_outside(leg, workspace, _WORKSPACE_CHECK_STRIDE,
                             _WORKSPACE_COARSE_BLOCKS)[0] == expected
        assert first_outside(leg, workspace, 1)[0] == expected
        rejected += expected >= 0
    # Both outcomes were tried.
    assert 10 < rejected < 55
