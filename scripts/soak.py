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
Long runs: resident memory over many plans and over time (issue 13, item 4).

``plans``: ``plan_cycle`` in this process on seeded random reachable pairs, cycled (each
plan starts where the one before it ended); the resident set size (VmRSS) is sampled every
``--every`` plans and the growth after the first sample is reported, with the slope over
the second half of the run. Each sample also gives the Python heap (blocks allocated by
CPython's small-object allocator, where every Python object and NumPy array header lives:
a leak of objects grows it) and, with ``--trim``, VmRSS again after glibc's
``malloc_trim(0)`` has returned every free page to the system: memory that is freed but
kept by the allocator then no longer counts. Run it with ``MALLOC_ARENA_MAX`` or
``MALLOC_MMAP_THRESHOLD_`` set to compare allocator policies; the summary gives the CPU time
per plan after the first sample, and its system part.

``node``: ``ellipath_node`` as a subprocess under continuous valid pairs from this process
for ``--minutes`` (the flood of ``scripts/flood.py`` at a low rate, so that the queue stays
busy without being flooded). Every ``--every`` seconds the node's VmRSS and its parts
(anonymous, file-backed, shared memory) are sampled with how many statuses and trajectories
it had published. The first ``--warm-up-pairs`` pairs (1,000) are sent at ``--warm-up-rate``
(1.6 pairs/s), the rest at ``--rate``. The warm-up ends when every bounded buffer that the
pairs fill is full and the node has planned as many pairs as the planner takes to fill its
own caches (see BUFFERS, WARM_UP_PLANS): the growth reported is the growth after it, and the
verdict is ``flat`` when the least-squares line through the samples after the warm-up rises
by at most ``--flat-kib`` over that time, for VmRSS and for its anonymous part.

One SIGINT or SIGTERM stops either soak, also when started in the background with SIGINT
ignored: ``plans`` after the plan in progress, printing the summary of the plans done;
``node`` stops its node and exits with status 1 without a report.

    .venv/bin/python scripts/soak.py plans --plans 100000 --trim
    ROS_DOMAIN_ID=61 .venv/bin/python scripts/soak.py node --minutes 30 --rate 1
"""

import argparse
import ctypes
import json
import os
import signal
import sys
import threading
import time

from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.settings import default_of
from ellipath_ros.node import DIAGNOSTICS_DEPTH
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import flood  # noqa: E402, I100 (a sibling script: scripts/ is not a package)

HOME = np.array([0.0, 0.0, -0.8])
# Distinct pairs cycled through: enough to exercise many geometries, few enough that the
# inputs themselves take no memory worth counting.
DISTINCT_PAIRS = 500
# The node's bounded buffers that continuous pairs fill, as (sample key, bound): the writer
# histories of /diagnostics (KEEP_LAST DIAGNOSTICS_DEPTH, one sample per status) and of
# joint_trajectory (KEEP_LAST queue_depth). Fast DDS drops a sample from a VOLATILE writer's
# history once every reader has acknowledged it, so with a prompt reader these hold far less:
# counting the warm-up until they could be full is the cautious bound. The intake's
# KEEP_ALL histories, the cycle queue and the waiting picks hold what the node has not yet
# read or planned, a few pairs at a rate the node keeps up with.
# The planner's own fill: in one process the Python heap and the memory in use rise over the
# first ~1,000 plans (CPython's free lists, NumPy's caches, the kernels' first calls on new
# code paths) and are level after it (docs/reliability.md, "The node over time": the plans
# soak every 50 plans). In the node the warm-up waits for as many trajectories, sent at
# --warm-up-rate so that it does not take most of a 30-minute run at 1 pair/s.
WARM_UP_PLANS = 1_000
# A default cycle of the soak's pairs lasts 0.42 to 0.53 s and the node releases them back to
# back: up to about 1.9 pairs/s. Below that every warm-up pair is planned (none queue_full),
# and 1,000 take about 10 minutes.
WARM_UP_RATE = 1.6  # pairs/s
BUFFERS = {'diagnostics_history': ('statuses', DIAGNOSTICS_DEPTH),
           'trajectory_history': ('trajectories', default_of('queue_depth')),
           'planner_fill': ('trajectories', WARM_UP_PLANS)}
# Growth after the warm-up still called flat [KiB] (the samples move by a few hundred KiB
# as large NumPy arrays are mapped and unmapped, see node.MALLOC_MMAP_THRESHOLD).
FLAT_KIB = 256
MEMORY_KEYS = ('rss', 'anon', 'file', 'shmem')


def random_point(rng):
    """Return a point of the default safe workspace, low enough for the arc to stay in it."""
    radius = 0.3 * np.sqrt(rng.uniform())
    angle = rng.uniform(0.0, 2.0 * np.pi)
    return np.array([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(-0.95, -0.7)])


def soak_plans(plans, every, seed, trim=False, stop=None):
    """
    Plan ``plans`` cycles, print a JSON line per RSS sample, return the summary dict.

    ``stop`` (a :class:`threading.Event`): once set, the run ends after the plan in progress
    and the summary covers the plans done (``stopped`` true).
    """
    # glibc only: malloc_trim(0) gives every wholly free page of every arena back.
    malloc_trim = ctypes.CDLL('libc.so.6').malloc_trim if trim else None
    rng = np.random.default_rng(seed)
    config = PlannerConfig()
    pairs = [(random_point(rng), random_point(rng)) for _ in range(DISTINCT_PAIRS)]
    start = HOME
    samples = []
    planned = rejected = 0
    started = time.monotonic()
    for index in range(plans):
        if stop is not None and stop.is_set():
            break
        pick, place = pairs[index % DISTINCT_PAIRS]
        try:
            start = plan_cycle(start, pick, place, config).end_position
            planned += 1
        except EllipathError:
            rejected += 1  # a pair this start cannot reach safely: the next one starts here
        if (index + 1) % every == 0:
            sample = {'plans': index + 1, 'planned': planned, 'rejected': rejected,
                      'rss_kib': flood.resident_kib(os.getpid()),
                      'python_blocks': sys.getallocatedblocks(),
                      'elapsed_s': round(time.monotonic() - started),
                      'cpu_s': round(time.process_time(), 3),
                      'system_s': round(os.times().system, 3)}
            if malloc_trim is not None:
                malloc_trim(0)
                sample['rss_trimmed_kib'] = flood.resident_kib(os.getpid())
            samples.append(sample)
            print(json.dumps(sample), flush=True)
    result = summary(samples, 'plans')
    result.update(plans_done=planned + rejected, stopped=stop is not None and stop.is_set())
    return result


def summary(samples, count_key):
    """Return the RSS figures of ``samples`` (growth counted from the first sample)."""
    if not samples:
        return {'samples': 0}
    rss = [sample['rss_kib'] for sample in samples]
    result = {'samples': len(samples), count_key: samples[-1][count_key],
              'rss_first_kib': rss[0], 'rss_last_kib': rss[-1], 'rss_max_kib': max(rss),
              'growth_kib': rss[-1] - rss[0], 'growth_max_kib': max(rss) - rss[0]}
    if len(samples) >= 2 and 'cpu_s' in samples[0]:
        # CPU per plan after the first sample (the first plans fill caches), the system's
        # part apart: mapping and unmapping memory is system time (see MALLOC_MMAP_THRESHOLD).
        counted = samples[-1][count_key] - samples[0][count_key]
        for key in ('cpu_s', 'system_s'):
            result[f'{key[:-2]}_ms_per_plan'] = round(
                1e3 * (samples[-1][key] - samples[0][key]) / counted, 2)
    half = samples[len(samples) // 2:]
    if len(half) >= 2:
        # Least-squares slope of VmRSS over the second half, per 1,000 of count_key.
        counts = np.array([sample[count_key] for sample in half], dtype=float)
        for key in ('rss_kib', 'rss_trimmed_kib', 'python_blocks'):
            if key in half[0]:
                values = np.array([sample[key] for sample in half], dtype=float)
                result[f'{key}_per_1000_second_half'] = round(
                    1e3 * float(np.polyfit(counts, values, 1)[0]), 1)
    return result


def soak_node(minutes, rate, seed, every=10.0, flat_kib=FLAT_KIB,
              warm_up_pairs=WARM_UP_PLANS, warm_up_rate=WARM_UP_RATE):
    """
    Run the node for ``minutes``; return the flood's report with the memory verdict.

    The first ``warm_up_pairs`` pairs are sent at ``warm_up_rate`` pairs/s, the rest at
    ``rate`` (see WARM_UP_PLANS).
    """
    report = flood.run(rate=rate, seconds=60.0 * minutes, seed=seed, rss_every=every,
                       invalid_share=0.0, out=sys.stderr,
                       warm_up=(warm_up_pairs, warm_up_rate) if warm_up_pairs else None)
    report.update(warm_up_pairs=warm_up_pairs, warm_up_rate=warm_up_rate)
    report['memory'] = memory_verdict(report.pop('memory_samples'), flat_kib)
    return report


def warm_up(samples, buffers=BUFFERS):
    """
    Return (when each buffer of ``buffers`` was full, the end of the warm-up) [s].

    A buffer is full at the first sample whose count reached its bound (None: never); the
    warm-up ends when the last of them is (None if one never is).
    """
    full = {}
    for name, (key, bound) in buffers.items():
        full[name] = next((sample['t'] for sample in samples if sample[key] >= bound), None)
    end = None if None in full.values() else max(full.values(), default=0.0)
    return full, end


def memory_verdict(samples, flat_kib=FLAT_KIB, buffers=BUFFERS):
    """
    Return the node's memory over the run: per minute, the warm-up, the growth after it.

    Growth after the warm-up, per part of the resident set (see MEMORY_KEYS): the last
    sample less the first at or after the warm-up, and the rise of the least-squares line
    through those samples over their time (robust to the samples' noise). ``verdict``:
    ``flat`` if that rise is at most ``flat_kib`` for VmRSS and for its anonymous part,
    ``growing`` if not, ``no warm-up`` if a buffer never filled or fewer than 3 samples
    followed.
    """
    full, end = warm_up(samples, buffers)
    per_minute = {}
    for sample in samples:
        per_minute.setdefault(int(sample['t'] // 60.0), sample)
    result = {'buffers': {name: {'bound': bound, 'full_at_s': full[name]}
                          for name, (_, bound) in buffers.items()},
              'warm_up_end_s': end, 'flat_kib': flat_kib,
              'per_minute_kib': {key: [per_minute[minute].get(key) for minute in
                                       sorted(per_minute)] for key in MEMORY_KEYS}}
    after = [] if end is None else [sample for sample in samples if sample['t'] >= end]
    if len(after) < 3:
        result['verdict'] = 'no warm-up'
        return result
    times = np.array([sample['t'] for sample in after], dtype=float)
    growth = {}
    for key in MEMORY_KEYS:
        values = np.array([sample[key] for sample in after], dtype=float)
        slope = float(np.polyfit(times, values, 1)[0])
        growth[key] = {'first_kib': int(values[0]), 'last_kib': int(values[-1]),
                       'last_less_first_kib': int(values[-1] - values[0]),
                       'fitted_rise_kib': round(slope * (times[-1] - times[0]), 1),
                       'per_10_min_kib': round(600.0 * slope, 1)}
    result.update(after_warm_up_s=round(float(times[-1] - times[0]), 1), growth=growth,
                  verdict='flat' if all(growth[key]['fitted_rise_kib'] <= flat_kib
                                        for key in ('rss', 'anon')) else 'growing')
    return result


def stop_on_signals(stop):
    """
    Make SIGINT and SIGTERM set ``stop`` (``plans``) or raise KeyboardInterrupt (None).

    Installed whatever this process inherited: a soak started in the background of a
    non-interactive shell (``nohup ... &``) starts with SIGINT ignored, and one SIGINT did
    not stop it (80,500 plans on eec5835); SIGTERM ended it without its summary.
    KeyboardInterrupt ends ``node`` through flood.run's cleanup, which stops the node.
    """
    def handler(signum, frame):
        if stop is None:
            raise KeyboardInterrupt(signal.Signals(signum).name)
        stop.set()

    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, handler)


def main():
    """Run the soak chosen on the command line and print its summary as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    commands = parser.add_subparsers(dest='command', required=True)
    plans = commands.add_parser('plans', help='plan_cycle in this process')
    plans.add_argument('--plans', type=int, default=100_000)
    plans.add_argument('--every', type=int, default=1000, help='plans between RSS samples')
    plans.add_argument('--seed', type=int, default=17)
    plans.add_argument('--trim', action='store_true',
                       help='also sample VmRSS after malloc_trim(0) (glibc)')
    node = commands.add_parser('node', help='ellipath_node under continuous pairs')
    node.add_argument('--minutes', type=float, default=30.0)
    node.add_argument('--rate', type=float, default=4.0, help='pairs per second')
    node.add_argument('--seed', type=int, default=17)
    node.add_argument('--every', type=float, default=10.0, help='seconds between samples')
    node.add_argument('--flat-kib', type=float, default=FLAT_KIB,
                      help='growth after the warm-up still called flat [KiB]')
    node.add_argument('--warm-up-pairs', type=int, default=WARM_UP_PLANS,
                      help='pairs sent first at --warm-up-rate (0: none)')
    node.add_argument('--warm-up-rate', type=float, default=WARM_UP_RATE,
                      help='pairs per second during the warm-up')
    options = parser.parse_args()
    if options.command == 'plans':
        stop = threading.Event()
        stop_on_signals(stop)
        result = soak_plans(options.plans, options.every, options.seed, options.trim, stop)
    else:
        stop_on_signals(None)
        try:
            result = soak_node(options.minutes, options.rate, options.seed, options.every,
                               options.flat_kib, options.warm_up_pairs, options.warm_up_rate)
        except KeyboardInterrupt as interrupt:
            print(json.dumps({'summary': {'stopped': True, 'signal': str(interrupt)}}),
                  flush=True)
            return 1
    print(json.dumps({'summary': result}), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
