#!/usr/bin/env python3
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
Belt cycles onto a place belt at an angle to the pick belt, checked on the executed motion.

Seeded cases: both belts at 0.1-0.5 m/s, the place belt at 90, -90, 45, 135, 180 degrees or a
random angle to the pick belt (random direction), objects latched 0.2 m upstream and up to
0.1 m aside, places and starts within 0.2 m of the axis, 50 ms dwells. Executed = JTC's
quintic through the published points, through forward kinematics (the dense check of
``executed_limits.py``). Prints the worst TCP-to-place distance at the place instant, the
worst speed relative to the tray in the place dwell, the worst peaks as shares of the limits,
the pick dwell's extension, the CPU per belt plan (``time.process_time``) and the time to the
end of the place dwell against the same cycle with a still place.

    python3 scripts/angled_place_check.py --cases 20 --seed 0
"""

import argparse
import os
import sys
import time

from ellipath_ros.core.conveyor import Conveyor
from ellipath_ros.core.conveyor import plan_belt_cycle
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.planner import PlannerConfig
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import executed_limits  # noqa: E402, I100 (scripts/ is not a package)

DWELL = 0.05
ANGLES = (90.0, -90.0, 45.0, 135.0, 180.0)


def _belt(speed, degrees):
    angle = np.radians(degrees)
    return speed * np.array([np.cos(angle), np.sin(angle), 0.0])


def _executed(plan, t, config):
    q, _, _ = quintic_interpolate(plan.joint_trajectory, np.asarray(t, dtype=float))
    return forward_kinematics(q, config.geometry)


def _place_end(plan):
    """Return the trajectory time at which the TCP reaches the place."""
    return plan.metrics['belt.pick_after_start'] + DWELL + plan.legs[1].motion.duration


def main():
    """Plan the seeded cases; print the executed figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--cases', type=int, default=20)
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    config = PlannerConfig()
    limits, joints = config.limits, config.joint_limits
    bounds = np.array([limits.max_speed, limits.max_accel, limits.max_jerk,
                       joints.max_velocity, joints.max_acceleration])
    worst_place = worst_relative = 0.0
    worst_peaks = np.zeros(5)
    extensions, cpu, ratios, failed = [], [], [], []
    for case in range(args.cases):
        degrees = rng.uniform(-180.0, 180.0)
        speed = rng.uniform(0.1, 0.5)
        turn = rng.choice(ANGLES + (rng.uniform(-180.0, 180.0),))
        velocity, tray = _belt(speed, degrees), _belt(rng.uniform(0.1, 0.5), degrees + turn)
        direction = velocity / speed
        aside = np.array([-direction[1], direction[0], 0.0]) * rng.uniform(-0.1, 0.1)
        pick = -0.2 * direction + aside + np.array([0.0, 0.0, -0.85])
        place = np.array([*rng.uniform(-0.2, 0.2, 2), -0.8])
        start = np.array([*rng.uniform(-0.2, 0.2, 2), -0.78])
        options = {'pick_dwell': DWELL, 'place_dwell': DWELL, 'start_time': 0.02}
        try:
            began = time.process_time()
            plan = plan_belt_cycle(start, pick, place, config,
                                   Conveyor(velocity=velocity, place_velocity=tray), **options)
            cpu.append(time.process_time() - began)
            still = plan_belt_cycle(start, pick, place, config, Conveyor(velocity=velocity),
                                    **options)
        except EllipathError as error:
            failed.append(f'case {case}: {error.kind}: {error}')
            continue
        extensions.append(plan.metrics['belt.pick_dwell_extension'])
        arrival = _place_end(plan)
        worst_place = max(worst_place, float(np.linalg.norm(
            _executed(plan, [arrival], config)[0] - place)))
        h = 1e-5
        t = np.linspace(arrival + h, arrival + DWELL - h, 101)
        relative = (_executed(plan, t + h, config) - _executed(plan, t - h, config)) / (2 * h)
        worst_relative = max(worst_relative,
                             float(np.linalg.norm(relative - tray, axis=1).max()))
        peaks = executed_limits.dense_check(plan.joint_trajectory, config.geometry, 4e-6, 5)
        worst_peaks = np.maximum(worst_peaks, peaks / bounds)
        ratios.append((arrival + DWELL) / (_place_end(still) + DWELL))
    print(f'{args.cases} cases, {len(failed)} failed' + ''.join(f'\n  {line}' for line in failed))
    if not extensions:
        return
    print(f'executed: TCP to place at the place instant max {worst_place * 1e3:.2g} mm; speed '
          f'relative to the tray in the place dwell max {worst_relative * 1e3:.2g} mm/s')
    print('executed peaks / limits (speed, accel, jerk, joint velocity, joint accel): '
          + ', '.join(f'{value:.4f}' for value in worst_peaks))
    extensions, cpu = np.array(extensions) * 1e3, np.array(cpu) * 1e3
    print(f'pick dwell extension median {np.median(extensions):.2f} ms, max '
          f'{extensions.max():.2f} ms; CPU per plan median {np.median(cpu):.0f} ms, max '
          f'{cpu.max():.0f} ms')
    print(f'time to the end of the place dwell, angled place belt / still place: median '
          f'{np.median(ratios):.3f}, range {min(ratios):.3f}-{max(ratios):.3f}')


if __name__ == '__main__':
    main()
