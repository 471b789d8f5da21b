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
What the safe-workspace check of the executed motion costs per plan.

Plans seeded random pairs (pick and place in the default workspace, from home) with the
default configuration and times the check (quintic interpolation of the leg's points at
0.1 ms, forward kinematics, cylinder and box tests) inside each plan; prints the median and
p90 of the check time, of the whole plan time and their ratio. Planned with two keep-out
boxes that no path touches, so the box test runs but rejects nothing.

    .venv/bin/python scripts/workspace_check_cost.py --pairs 60
"""

import argparse
import statistics
import sys
import time

from ellipath_ros.core import planner
from ellipath_ros.core.errors import EllipathError
import numpy as np

HOME = np.array([0.0, 0.0, -0.8])
# Far from every path of the sample: the box test runs without rejecting anything.
BOXES = (0.5, 0.5, -1.0, 0.6, 0.6, -0.9, -0.6, -0.6, -1.0, -0.5, -0.5, -0.9)


def random_point(rng):
    """Return a point of the default workspace, low enough for the arc to stay in it."""
    radius = 0.3 * np.sqrt(rng.uniform())
    angle = rng.uniform(0.0, 2.0 * np.pi)
    return np.array([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(-0.95, -0.7)])


def main():
    """Plan the pairs, time the check, print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--pairs', type=int, default=60)
    parser.add_argument('--seed', type=int, default=13)
    options = parser.parse_args()
    rng = np.random.default_rng(options.seed)
    config = planner.PlannerConfig.from_flat({'keep_out_boxes': list(BOXES)})
    checked = planner._check_executed_workspace
    spent = []

    def timed_check(*args, **kwargs):
        started = time.perf_counter()
        try:
            return checked(*args, **kwargs)
        finally:
            spent.append(time.perf_counter() - started)

    planner._check_executed_workspace = timed_check
    check_times, plan_times, rejected = [], [], 0
    planner.plan_cycle(HOME, [0.1, 0.0, -0.8], [-0.1, 0.0, -0.8], config)  # warm-up
    for _ in range(options.pairs):
        spent.clear()
        try:
            plan = planner.plan_cycle(HOME, random_point(rng), random_point(rng), config)
        except EllipathError:
            rejected += 1
            continue
        check_times.append(sum(spent))
        plan_times.append(plan.metrics['plan_time'])
    ratios = [check / plan for check, plan in zip(check_times, plan_times)]

    def quantiles(values, scale):
        ordered = sorted(values)
        return (f'median {statistics.median(ordered) * scale:.3g}, '
                f'p90 {ordered[int(0.9 * (len(ordered) - 1))] * scale:.3g}')

    print(f'{len(plan_times)} plans ({rejected} pairs rejected), default config + 2 boxes')
    print(f'workspace check per plan [ms]: {quantiles(check_times, 1e3)}')
    print(f'whole plan time [ms]:          {quantiles(plan_times, 1e3)}')
    print(f'check / plan time [%]:         {quantiles(ratios, 1e2)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
