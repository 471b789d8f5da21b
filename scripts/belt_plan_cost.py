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
CPU per belt plan on seeded cases, and how many leg timings and point searches each takes.

Belts at 0.1-0.5 m/s in random horizontal directions, objects latched up to 0.45 m upstream
of the base axis and 0.15 m aside, places and starts within 0.2 m of the axis, 35 ms dwells.
CPU time (``time.process_time``), so that other processes on a shared machine count less.

    python3 scripts/belt_plan_cost.py --cases 20
"""

import argparse
import time

from ellipath_ros.core import conveyor
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.planner import PlannerConfig
import numpy as np


def _counting(name, counts):
    """Make conveyor's ``name`` count its calls in ``counts[name]``."""
    original = getattr(conveyor, name)

    def counted(*args, **kwargs):
        counts[name] += 1
        return original(*args, **kwargs)

    setattr(conveyor, name, counted)


def main():
    """Plan the seeded cases; print CPU p50/max and the counts per plan."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--cases', type=int, default=20)
    parser.add_argument('--seed', type=int, default=7)
    args = parser.parse_args()
    counts = {'time_motion': 0, '_joint_points': 0}
    for name in counts:
        _counting(name, counts)
    rng = np.random.default_rng(args.seed)
    config = PlannerConfig()
    cpu, timings, searches, outcomes = [], [], [], {}
    for _ in range(args.cases):
        angle = rng.uniform(0.0, 2.0 * np.pi)
        direction = np.array([np.cos(angle), np.sin(angle), 0.0])
        belt = conveyor.Conveyor(velocity=rng.uniform(0.1, 0.5) * direction,
                                 window_upstream=-0.3, window_downstream=0.25)
        aside = np.cross([0.0, 0.0, 1.0], direction) * rng.uniform(-0.15, 0.15)
        pick = aside + direction * rng.uniform(-0.45, 0.0) + np.array([0.0, 0.0, -0.85])
        place = np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), -0.8])
        start = np.array([rng.uniform(-0.15, 0.15), rng.uniform(-0.15, 0.15), -0.8])
        start_time = rng.uniform(0.0, 0.5)
        counts.update(time_motion=0, _joint_points=0)
        began = time.process_time()
        try:
            conveyor.plan_belt_cycle(start, pick, place, config, belt, pick_dwell=0.035,
                                     place_dwell=0.035, latch_time=0.0, start_time=start_time)
            outcome = 'planned'
        except EllipathError as error:
            outcome = error.kind
        cpu.append(time.process_time() - began)
        timings.append(counts['time_motion'])
        searches.append(counts['_joint_points'])
        outcomes[outcome] = outcomes.get(outcome, 0) + 1
    cpu = np.array(cpu) * 1e3
    print(f'{args.cases} belt plans {outcomes}: CPU p50 {np.median(cpu):.0f} ms, '
          f'max {cpu.max():.0f} ms; leg timings per plan median {np.median(timings):.0f}, '
          f'max {max(timings)}; point searches per plan median {np.median(searches):.0f}, '
          f'max {max(searches)}')


if __name__ == '__main__':
    main()
