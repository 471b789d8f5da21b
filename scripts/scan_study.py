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
Cost and result of the time-optimal profile per leg (issue 11, issue 14 item 4): a study.

The legs are those the planner times for seeded random requests
(:func:`ellipath_ros.bench.latency.random_pairs`, chained from the default home position as
the bench chains them): per pair the approach leg (when the pick is not where the robot is)
and the transfer leg, each with the planner's joint-velocity speed cap, default settings.
Per leg it measures the CPU time (``time.process_time``) of the profile's construction
(``_optimal_motion``: the arc scan and the Ruckig lines, without the final limit check) and
the planned duration that ``time_motion`` returns (after the final check). It also plans the
bench's cycles (``ellipath bench`` cycle rows, time-optimal profile, planned durations over
TOPP-RA's bound).

Run it with this checkout's code (the step counter reads the scanners' step budgets); the
legs depend on the geometry and the pairs only. The kernels are compiled (or loaded from
numba's cache) before anything is measured.
``--save FILE`` writes the figures as JSON (e.g. with main's venv, as the baseline);
``--baseline FILE`` compares this run's durations with such a file leg by leg (default:
``scripts/data/scan_baseline.json``, main 509a3bb's figures for the default 160 pairs, CPU
times measured on the shared 2-core machine under load; compare CPU times of runs made
side by side, steps anywhere).

    PYTHONPATH=. python3 scripts/scan_study.py [--pairs N] [--save F] [--baseline F]
"""

import argparse
import json
import os
import sys
import time

from ellipath_ros.bench.cycle import cycle_rows
from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core import arc_scan, optimal_profile, planner
from ellipath_ros.core.compiled import warm_up
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.geometry import plan_path
from ellipath_ros.core.settings import default_of
from ellipath_ros.core.timing import time_motion
import numpy as np

DEFAULT_PAIRS = 160
DEFAULT_BASELINE = os.path.join(os.path.dirname(__file__), 'data', 'scan_baseline.json')
SAME_POINT = 1e-9


def legs(count):
    """Yield (label, path, speed cap, config) of the legs of ``count`` chained random pairs."""
    config = planner.PlannerConfig()
    start = np.asarray(default_of('home_position'), dtype=float)
    for index, (pick, place) in enumerate(random_pairs(count)):
        ends = [('transfer', pick, place, config.pick_clearance, config.place_clearance)]
        if np.linalg.norm(pick - start) > SAME_POINT:
            ends.insert(0, ('approach', start, pick, config.place_clearance,
                            config.pick_clearance))
        for leg, begin, end, first, second in ends:
            try:
                path = plan_path(begin, end, first, second, config.arc, config.join,
                                 config.join_tolerance)
                cap = planner._check_reach_and_speed_cap(path, config)
            except EllipathError:
                continue
            yield f'{index}-{leg}', path, cap, config
        start = place


class StepCounter:
    """Counts the scan's steps (what the scanners' step budgets spent) while the block runs."""

    def __init__(self):
        # The budgets the scanners were made with: {id: (budget array, steps at the start)}.
        self._budgets = {}
        self._init = arc_scan._Scanner.__init__

    def __enter__(self):
        original, budgets = self._init, self._budgets

        def recorded(scanner, table, cell, limits, budget):
            original(scanner, table, cell, limits, budget)
            budgets.setdefault(id(budget), (budget, int(budget[0])))
        arc_scan._Scanner.__init__ = recorded
        return self

    def __exit__(self, *exception):
        arc_scan._Scanner.__init__ = self._init

    @property
    def steps(self):
        """Return the steps taken (a budget below 0 ran out: what found it spent took no step)."""
        return sum(start - max(int(budget[0]), 0) for budget, start in self._budgets.values())


def measure_legs(count):
    """Return {label: (CPU s of _optimal_motion, planned duration, scan steps)} per leg."""
    warm_up()
    figures = {}
    for label, path, cap, config in legs(count):
        started = time.process_time()
        try:
            optimal_profile._optimal_motion(path, config.limits, cap)
        except EllipathError:
            continue
        cpu = time.process_time() - started
        with StepCounter() as counter:
            duration = time_motion(path, config.limits, speed_cap=cap).duration
        figures[label] = (cpu, duration, counter.steps)
    return figures


def measure_cycles():
    """Return {case/join/jump: ratio to TOPP-RA's bound} of the bench's time-optimal cycles."""
    return {f"{row['case']} / {row['join']} @{row['max_accel_jump']:g}": row['ratio_to_bound']
            for row in cycle_rows(profiles=('time_optimal',))}


def report(figures, cycles, baseline):
    """Print the CPU percentiles, the cycle ratios and the comparison with ``baseline``."""
    cpu = 1e3 * np.array([value[0] for value in figures.values()])
    p50, p99 = np.percentile(cpu, [50.0, 99.0])
    steps = np.array([value[2] for value in figures.values()])
    print(f'legs: {cpu.size}; CPU of _optimal_motion per leg [ms]: p50 {p50:.1f}, '
          f'p99 {p99:.1f}, max {cpu.max():.1f}; over 50 ms: {int((cpu > 50.0).sum())}; '
          f'scan steps per leg: {steps_line(steps)}')
    for name, ratio in cycles.items():
        before = (baseline or {}).get('cycles', {}).get(name)
        change = '' if before is None else f' (baseline {before:.4f}, {ratio / before - 1:+.2%})'
        print(f'  cycle {name}: planned ratio to TOPP-RA {ratio:.4f}{change}')
    if baseline is None:
        return
    common = sorted(set(figures) & set(baseline['legs']))
    after = np.array([figures[label][1] for label in common])
    before = np.array([baseline['legs'][label][1] for label in common])
    change = after / before - 1.0
    cpu_before = 1e3 * np.array([baseline['legs'][label][0] for label in common])
    p50_b, p99_b = np.percentile(cpu_before, [50.0, 99.0])
    steps_before = np.array([baseline['legs'][label][2] for label in common])
    print(f'baseline CPU per leg [ms]: p50 {p50_b:.1f}, p99 {p99_b:.1f}, '
          f'max {cpu_before.max():.1f}; scan steps per leg: {steps_line(steps_before)}')
    print(f'planned durations on {len(common)} common legs: mean {after.mean():.5f} s vs '
          f'{before.mean():.5f} s ({after.mean() / before.mean() - 1:+.3%}); per leg change '
          f'min {change.min():+.2%}, median {np.median(change):+.3%}, max {change.max():+.2%}; '
          f'slower by > 0.5 %: {int((change > 5e-3).sum())}, faster by > 0.5 %: '
          f'{int((change < -5e-3).sum())}')
    worst = np.argsort(change)[::-1][:5]
    print('  slowest relative to baseline: ' + ', '.join(
        f'{common[index]} {change[index]:+.2%}' for index in worst))
    missing = len(set(baseline['legs']) - set(figures))
    if missing:
        print(f'  legs of the baseline not planned here: {missing}')


def steps_line(steps):
    """Return the scan steps' median, 99th percentile and maximum as text."""
    p50, p99 = np.percentile(steps, [50.0, 99.0])
    return f'p50 {p50:.0f}, p99 {p99:.0f}, max {steps.max()}'


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--pairs', type=int, default=DEFAULT_PAIRS)
    parser.add_argument('--save', help='write the figures as JSON to this file')
    parser.add_argument('--baseline', default=DEFAULT_BASELINE,
                        help='compare with figures saved by --save ("" for none)')
    parser.add_argument('--no-cycles', action='store_true', help='skip the bench cycles')
    options = parser.parse_args(argv)
    figures = measure_legs(options.pairs)
    cycles = {} if options.no_cycles else measure_cycles()
    baseline = None
    if options.baseline:
        with open(options.baseline, encoding='utf-8') as stream:
            baseline = json.load(stream)
    report(figures, cycles, baseline)
    if options.save:
        legs_text = ',\n'.join(f'{json.dumps(label)}: {json.dumps(value)}'
                               for label, value in figures.items())
        with open(options.save, 'w', encoding='utf-8') as stream:
            stream.write(f'{{"cycles": {json.dumps(cycles)},\n"legs": {{\n{legs_text}}}}}\n')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
