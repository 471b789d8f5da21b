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
``ellipath bench``: how fast the planner answers, and how fast the cycles it plans are.

:func:`run_bench` measures, with the node's default parameters:

* ``latency``: wall times [ms] as ``{p50, p99, max, n}`` of a whole request (``plan_cycle``
  from the start through pick to place, both legs, every check, the points, plus building
  the JointTrajectory message), of one leg (``plan_transfer``), of the same requests with
  the ``curvature`` profile, of building and serialising the message, and end to end
  (place pose published by this process, trajectory received from ``ellipath_node`` in
  another process), and of the end-to-end time less the node's own plan_time of the pair
  (``e2e_outside_plan_ms``: intake, thread hand-overs, DDS); the node plans a pair's approach
  leg as its pick arrives, so end to end is also measured from the pick
  (``e2e_from_pick_ms``) and the pairs whose approach was planned ahead are counted
  (``latency_notes.e2e_ms.approach_preplanned``); see :mod:`.latency` and :mod:`.e2e`;
* ``cycle``: planned durations of the paper's example and the 25-305-25 mm cycle against
  TOPP-RA's bound (:mod:`.cycle`);
* ``messages``: the points and serialized bytes of each request's message (p50, p99, max);
* ``executed``: the worst executed (JTC-interpolated) TCP speed, acceleration and jerk over
  the latency requests, as ratios to the limits;
* ``picks_per_min`` on the 25-305-25 mm cycle, beside ABB's quoted IRB 360 figure;
* ``machine``: CPU, cores, load, Python, NumPy, numba and Ruckig versions.

``MODES`` sizes the full run and ``--quick``: a pair count per section and a wall-time budget
per section; a section that reaches its budget stops there and says so (``n`` is what was
measured).
"""

from importlib import metadata
import os
import platform
import sys
import time

import numpy as np

from .cycle import cycle_rows, picks_per_minute, topp_bound
from .e2e import EndToEndError, measure_end_to_end
from .latency import (
    DEFAULT_SEED, executed_peaks, latency_stats, measure_curvature_requests, measure_legs,
    measure_messages, measure_requests, message_sizes, MIN_HORIZONTAL_OFFSET, random_pairs,
    WORKSPACE_RADIUS, WORKSPACE_Z)

__all__ = ['MODES', 'run_bench', 'format_report', 'topp_bound']

# Pairs and wall-time budgets [s] per section, full run and --quick. With the cycle section
# (about 7 s on a loaded 2-core machine), the node's start and discovery, the full run takes
# at most about 2.7 min and --quick about 30 s. The request section has most of the time:
# at 65 ms a request it measures all 1000 pairs; the leg and curvature sections repeat
# requests it has measured, and stop at their budgets first. An e2e pair takes about 0.6 s
# (its trajectory's duration: the next pair must find the robot idle), so --quick's e2e
# budget holds about 25 pairs (3 s held 5, too few for a p99).
MODES = {
    'full': {'pairs': 1000, 'e2e_pairs': 100,
             'budget_s': {'request': 65.0, 'leg': 15.0, 'curvature': 20.0, 'executed': 10.0,
                          'e2e': 35.0}},
    'quick': {'pairs': 150, 'e2e_pairs': 40,
              'budget_s': {'request': 3.0, 'leg': 1.5, 'curvature': 1.5, 'executed': 1.0,
                           'e2e': 15.0}},
}
DEFAULT_DOMAIN_ID = 78


class Progress:
    """One progress line on stderr: rewritten in place on a terminal, one line per section."""

    def __init__(self, stream=sys.stderr):
        self._stream = stream
        self._tty = stream.isatty()

    def __call__(self, label, count, total, finished=False):
        """Report ``count`` of ``total`` items of section ``label`` (``finished``: its end)."""
        text = f'ellipath bench: {label} {count}/{total}'
        if self._tty:
            self._stream.write('\r' + text.ljust(60) + ('\n' if finished else ''))
        elif finished:
            self._stream.write(text + '\n')
        else:
            return
        self._stream.flush()


def machine():
    """Return the CPU model, cores, load average and the versions that set the speed."""
    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo') as cpuinfo:
            cpu = next((line.split(':', 1)[1].strip() for line in cpuinfo
                        if line.startswith('model name')), cpu)
    except OSError:
        # Not Linux: keep platform's answer.
        pass
    return {'cpu': cpu, 'cores': os.cpu_count(), 'load_average': list(os.getloadavg()),
            'python': platform.python_version(), 'numpy': np.__version__,
            'numba': metadata.version('numba'), 'ruckig': metadata.version('ruckig')}


def run_bench(mode='full', pairs=None, e2e_pairs=None, seed=None, domain_id=None,
              progress=None):
    """
    Run every section of the benchmark; return the JSON-ready result.

    Parameters
    ----------
    mode : str
        ``'full'`` or ``'quick'`` (see ``MODES``).
    pairs, e2e_pairs : int, optional
        Override the mode's pair counts (in-process sections, end to end).
    seed : int, optional
        Seed of the random pairs (``DEFAULT_SEED``, 2023, when omitted).
    domain_id : int, optional
        ROS domain of the end-to-end section (default ``ROS_DOMAIN_ID``, else 78).
    progress : callable, optional
        Progress reporter; :class:`Progress` on stderr by default.

    Returns
    -------
    dict
        ``latency``, ``cycle``, ``executed``, ``picks_per_min``, ``machine`` and the
        run's ``pairs``, ``mode`` and ``run_time_s``.

    Raises
    ------
    ImportError
        TOPP-RA is not installed (``pip install .[bench]``).

    """
    from ellipath_ros.core.compiled import warm_up
    from ellipath_ros.core.settings import default_values
    from ellipath_ros.malloc_policy import set_malloc_policy
    from ellipath_ros.node import freeze_start_up_objects
    from ellipath_ros.parameters import build_settings

    # This process plans as the node does, so first glibc's malloc policy that the
    # ellipath_node command sets before anything else (unless the environment sets one):
    # under glibc's default thresholds a request faulted in 12 fresh pages at the median
    # (34 on average over 300 pairs), under the node's 1 (6).
    node_malloc_policy = set_malloc_policy()
    began = time.perf_counter()
    seed = DEFAULT_SEED if seed is None else seed
    progress = progress or Progress()
    sizes = MODES[mode]
    budgets = sizes['budget_s']
    if domain_id is None:
        domain_id = int(os.environ.get('ROS_DOMAIN_ID') or DEFAULT_DOMAIN_ID)
    settings = build_settings(default_values())
    config = settings.planner
    result = {'mode': mode, 'machine': machine()}
    # TOPP-RA first: a missing extra fails before minutes of measuring.
    result['cycle'] = cycle_rows(
        config, progress=lambda done, total: progress('cycle', done, total, done == total))
    result['picks_per_min'] = picks_per_minute(config)

    # Every kernel loaded before timing, as the node does at start-up: a leg's first call
    # otherwise pays for loading the kernels its path needs (302 ms once). Then, as the node
    # does, what start-up made is kept out of the collector's full passes: one of them, in a
    # request, was each run's largest request time (see freeze_start_up_objects).
    warm_up()
    freeze_start_up_objects()
    drawn = random_pairs(pairs or sizes['pairs'], seed)
    home = settings.home_position
    requests_section, requests = measure_requests(drawn, home, settings, budgets['request'],
                                                  progress)
    sections = {
        'request_ms': requests_section,
        'leg_ms': measure_legs(requests, config, budgets['leg'], progress),
        'curvature_request_ms': measure_curvature_requests(
            requests, settings, budgets['curvature'], progress),
        'message_ms': measure_messages(requests, settings.frame_id, progress),
    }
    result['messages'] = message_sizes(requests)
    result['executed'] = executed_peaks(requests, config, budgets['executed'], progress)
    latency = {name: section.stats() for name, section in sections.items()}
    try:
        e2e = measure_end_to_end(requests[:e2e_pairs or sizes['e2e_pairs']], home, settings,
                                 domain_id, budgets['e2e'], progress)
        latency['e2e_ms'] = latency_stats(e2e['times'])
        latency['e2e_from_pick_ms'] = latency_stats(e2e['from_pick'])
        if e2e['plan_times']:
            latency['e2e_outside_plan_ms'] = latency_stats(
                np.subtract(e2e['times'], e2e['plan_times']).tolist())
        e2e_notes = {'budget_reached': e2e['budget_reached'], 'requested': e2e['requested'],
                     'budget_s': budgets['e2e'], 'mismatched': e2e['mismatched'],
                     'approach_preplanned': e2e['preplanned'], 'domain_id': domain_id}
    except EndToEndError as error:
        latency['e2e_ms'] = latency_stats([])
        e2e_notes = {'error': str(error), 'budget_s': budgets['e2e'], 'domain_id': domain_id}
    result['latency'] = latency
    result['latency_notes'] = {
        **{name: {'budget_reached': section.budget_reached, 'requested': section.requested,
                  'rejected': section.rejected, 'budget_s': section.budget_s}
           for name, section in sections.items()},
        'e2e_ms': e2e_notes,
        'node_malloc_policy': node_malloc_policy,
        'what': 'wall time on a steady clock, this machine as loaded as it was; e2e: each '
                'pair sent while the robot would be idle (the next one after the previous '
                "trajectory's duration), place published -> trajectory in the subscriber "
                '(e2e_from_pick: from the pick, published PICK_LEAD before the place)',
    }
    result['pairs'] = {
        'seed': seed, 'drawn': len(drawn), 'planned': len(requests),
        'workspace': {'radius_m': WORKSPACE_RADIUS, 'z_m': list(WORKSPACE_Z),
                      'min_horizontal_offset_m': MIN_HORIZONTAL_OFFSET},
        'start': 'home_position, then the last planned place',
    }
    result['config'] = {'profile': config.profile, 'join': getattr(config, 'join', 'paper'),
                        'output_mode': config.output_mode}
    result['run_time_s'] = time.perf_counter() - began
    return result


def _number(value, form):
    return '-' if value is None else format(value, form)


def format_report(result):
    """Return the human-readable report of a :func:`run_bench` result."""
    lines = [f"ellipath bench ({result['mode']}): {result['machine']['cpu']}, "
             f"{result['machine']['cores']} cores, load "
             + ' '.join(f'{load:.1f}' for load in result['machine']['load_average'])
             + f"; Python {result['machine']['python']}, NumPy {result['machine']['numpy']}, "
             f"numba {result['machine']['numba']}, Ruckig {result['machine']['ruckig']}",
             f"pairs: seed {result['pairs']['seed']}, {result['pairs']['planned']} planned of "
             f"{result['pairs']['drawn']} drawn; profile {result['config']['profile']}, join "
             f"{result['config']['join']}", '',
             '| latency [ms] | p50 | p99 | max | n | note |', '|---|---|---|---|---|---|']
    notes = result['latency_notes']
    for name, stats in result['latency'].items():
        note = notes.get(name, {})
        text = []
        if note.get('budget_reached'):
            text.append(f"budget {note['budget_s']:g} s reached, {stats['n']} of "
                        f"{note['requested']}")
        if note.get('rejected'):
            text.append('rejected ' + ', '.join(f'{count} {kind}'
                                                for kind, count in note['rejected'].items()))
        if note.get('error'):
            text.append(note['error'].splitlines()[0])
        if note.get('mismatched'):
            text.append(f"{note['mismatched']} not the in-process plan")
        if note.get('approach_preplanned') is not None:
            text.append(f"approach planned ahead for {note['approach_preplanned']} of "
                        f"{stats['n']}")
        lines.append(f"| {name[:-3]} | {_number(stats['p50'], '.1f')} | "
                     f"{_number(stats['p99'], '.1f')} | {_number(stats['max'], '.1f')} | "
                     f"{stats['n']} | {'; '.join(text)} |")
    messages = result['messages']
    if messages['n']:
        lines += ['', f"messages ({messages['n']} requests, both legs and the dwells): points "
                  f"p50 {messages['points']['p50']:.0f}, p99 {messages['points']['p99']:.0f}, "
                  f"max {messages['points']['max']}; serialized "
                  f"{messages['bytes']['p50'] / 1e3:.1f} / {messages['bytes']['p99'] / 1e3:.1f} "
                  f"/ {messages['bytes']['max'] / 1e3:.1f} kB"]
    executed = result['executed']
    lines += ['', f"executed (JTC's quintic through the published points, {executed['n']} "
              f"requests): worst speed {executed['speed']:.3f}, acceleration "
              f"{executed['accel']:.3f}, jerk {executed['jerk']:.3f} x the limits", '',
              'planned durations; TOPP-RA bounds without jerk limit, without and with the '
              'cap at the joins:', '',
              '| cycle | join | max accel jump [m/s²] | profile | duration [s] | '
              'bound [s] | ratio | bound, join cap [s] | ratio |', '|' + '---|' * 9]
    for row in result['cycle']:
        capped = row.get('topp_ra_bound_join_capped_s')
        lines.append(f"| {row['case']} | {row['join']} | {row['max_accel_jump']:g} | "
                     f"{row['profile']} | {row['duration_s']:.4f} | "
                     f"{row['topp_ra_bound_s']:.4f} | {row['ratio_to_bound']:.3f} | "
                     f"{_number(capped, '.4f')} | "
                     f"{_number(capped and row['duration_s'] / capped, '.3f')} |")
    picks = result['picks_per_min']
    reference = picks['reference']
    lines += ['', f"picks/min, {picks['cycle']} cycle, dwell "
              + ' + '.join(f'{dwell * 1e3:g}' for dwell in picks['dwell_s'])
              + ' ms (planned cycle time; JTC runs it in that time):', '',
              '| limits [m/s, m/s², m/s³] | joint limits | join | cycle [s] | picks/min |',
              '|---|---|---|---|---|']
    for row in picks['rows']:
        lines.append(f"| {row['limits']} ({row['max_speed']:g}, {row['max_accel']:g}, "
                     f"{row['max_jerk']:g}) | {row['joint_limits']} | {row['join']} | "
                     f"{row['cycle_s']:.4f} | {row['picks_per_min']:.1f} |")
    low, high = reference['picks_per_min']
    payload_low, payload_high = reference['payload_kg']
    lines.append(f"| {reference['robot']}, {payload_low:g}-{payload_high:g} kg | | | | "
                 f"{low}-{high} ({reference['source']}) |")
    lines.append(f"\nrun time {result['run_time_s']:.1f} s")
    return '\n'.join(lines) + '\n'
