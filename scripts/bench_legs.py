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
Durations and fallbacks of every leg of the bench's requests: a study of plan changes.

The requests are those of ``ellipath bench``: its seeded pairs (``random_pairs``), chained
as it chains them (the first from the node's ``home_position``, each later one from the
last planned place), planned by ``plan_cycle`` with the node's default settings (``--join``
overrides the join). Per leg: the duration ``time_motion`` returns (planned), the leg's
duration as published (after any slow-down for the executed limits), whether the
time-optimal profile's Ruckig fallback served it, and a digest of its published points (to
tell legs that changed at all).
``--save FILE`` writes them as JSON (e.g. with main's code on PYTHONPATH, as the baseline);
``--baseline FILE`` compares this run leg by leg: legs changed, by how much, totals.

    PYTHONPATH=. python3 scripts/bench_legs.py [--requests N] [--join J] [--save F]
"""

import argparse
import hashlib
import json
import logging
import sys

from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core import optimal_profile, planner
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.settings import default_values
from ellipath_ros.parameters import build_settings
import numpy as np

DEFAULT_REQUESTS = 1000
# A leg counts as changed when its published duration moved by more than this share.
CHANGED = 1e-12
LOG = logging.getLogger('bench_legs')


class LegRecorder:
    """Records, while the block runs, each ``time_motion`` of the planner and its fallbacks."""

    def __init__(self):
        self.calls = []
        self._time_motion = planner.time_motion
        self._fallback = optimal_profile._ArcPlanner.fallback

    def __enter__(self):
        calls, time_motion, fallback = self.calls, self._time_motion, self._fallback

        def timed(*args, **kwargs):
            calls.append([None, False])
            motion = time_motion(*args, **kwargs)
            calls[-1][0] = motion.duration
            return motion

        def recorded_fallback(arc_planner, *args):
            calls[-1][1] = True
            return fallback(arc_planner, *args)
        planner.time_motion = timed
        optimal_profile._ArcPlanner.fallback = recorded_fallback
        return self

    def __exit__(self, *exception):
        planner.time_motion = self._time_motion
        optimal_profile._ArcPlanner.fallback = self._fallback


def measure(count, join):
    """Return {label: (planned duration, published duration, fallback, digest)} per leg."""
    values = default_values()
    if join:
        values['join'] = join
    settings = build_settings(values)
    start = np.asarray(settings.home_position, dtype=float)
    figures = {}
    with LegRecorder() as recorder:
        for index, (pick, place) in enumerate(random_pairs(count)):
            recorder.calls.clear()
            try:
                plan = planner.plan_cycle(start, pick, place, settings.planner,
                                          pick_dwell=settings.pick_dwell,
                                          place_dwell=settings.place_dwell)
            except EllipathError:
                continue
            # plan_cycle times the transfer first, then the approach (listed first).
            names = ('transfer', 'approach')[:len(plan.legs)]
            for name, call, leg in zip(names, recorder.calls, reversed(plan.legs)):
                figures[f'{index}-{name}'] = (call[0], leg.motion.duration, call[1],
                                              digest(leg.joint_trajectory))
            start = plan.end_position
    return figures


def digest(trajectory):
    """Return a hex digest of a leg's published points (times, positions, speeds, accels)."""
    return hashlib.sha1(b''.join(np.ascontiguousarray(array).tobytes() for array in (
        trajectory.time_from_start, trajectory.positions, trajectory.velocities,
        trajectory.accelerations))).hexdigest()


def report(figures, baseline):
    """Log the legs, fallbacks and totals, and the comparison with ``baseline``."""
    fallbacks = sorted(label for label, value in figures.items() if value[2])
    LOG.info('legs %d, fallbacks %d (%s); total planned %.4f s, published %.4f s',
             len(figures), len(fallbacks), ', '.join(fallbacks),
             sum(value[0] for value in figures.values()),
             sum(value[1] for value in figures.values()))
    if baseline is None:
        return
    common = sorted(set(figures) & set(baseline))
    LOG.info('baseline: legs %d, fallbacks %d (%s); common legs %d', len(baseline),
             sum(value[2] for value in baseline.values()),
             ', '.join(sorted(label for label, value in baseline.items() if value[2])),
             len(common))
    LOG.info('published points changed on %d legs',
             sum(figures[label][3] != baseline[label][3] for label in common))
    for column, name in ((0, 'planned'), (1, 'published')):
        before = np.array([baseline[label][column] for label in common])
        after = np.array([figures[label][column] for label in common])
        change = after / before - 1.0
        changed = np.flatnonzero(np.abs(change) > CHANGED)
        LOG.info('%s: total %.4f s -> %.4f s (%+.3f %%); legs changed %d, slower %d '
                 '(worst %+.4f %%), faster %d (most %+.3f %%)', name, before.sum(),
                 after.sum(), 100.0 * (after.sum() / before.sum() - 1.0), changed.size,
                 int((change > CHANGED).sum()), 100.0 * max(change.max(), 0.0),
                 int((change < -CHANGED).sum()), 100.0 * min(change.min(), 0.0))
        for index in changed:
            LOG.info('  %s %.5f s -> %.5f s (%+.3f %%)%s', common[index], before[index],
                     after[index], 100.0 * change[index],
                     ' (was the fallback)' if baseline[common[index]][2] else '')


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--requests', type=int, default=DEFAULT_REQUESTS)
    parser.add_argument('--join', help="the join (the node's default if omitted)")
    parser.add_argument('--save', help='write the figures as JSON to this file')
    parser.add_argument('--baseline', help='compare with figures saved by --save')
    options = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format='%(message)s')
    figures = measure(options.requests, options.join)
    baseline = None
    if options.baseline:
        with open(options.baseline, encoding='utf-8') as stream:
            baseline = json.load(stream)
    report(figures, baseline)
    if options.save:
        with open(options.save, 'w', encoding='utf-8') as stream:
            json.dump(figures, stream, indent=0)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
