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
How well the timing's default samples find the planned peaks, on seeded random legs.

For each pair of ``random_pairs`` and each kind of leg (default settings, ``join
paper``, ``profile curvature`` with ``join paper``): the motion as the profile builds
it, before the final limit check, sampled as ``TimedMotion.sampled_norms`` samples it,
against a reference grid every ``--reference`` seconds plus both sides of every piece
bound (its peaks refined by the parabola through each local maximum and its
neighbours, computed here, the same for any version of the code). Then the planned
leg (``plan_transfer``): the reference peaks of its timed motion over the limits, its
duration, its point count and its interpolation error
(``planner._interpolation_error``, independent of the samples) over the tolerance.

Prints the largest relative differences (sample set - reference) / reference, the
largest reference peak ratios, and writes one JSON line per leg (``--legs``) to
compare two versions of the code leg by leg.
"""

import argparse
import dataclasses
import json
import sys

from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core import plan_transfer
from ellipath_ros.core.curvature_profile import _curvature_motion
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.geometry import plan_path
from ellipath_ros.core.motion import _sample_times, _sampled
from ellipath_ros.core.optimal_profile import _optimal_motion
from ellipath_ros.core.planner import _check_reach_and_speed_cap, _interpolation_error
from ellipath_ros.core.settings import default_values
from ellipath_ros.core.timing import time_motion
from ellipath_ros.parameters import build_settings
import numpy as np

KEYS = ('speed', 'accel', 'jerk')


def kinds():
    """Return the three kinds of legs: name -> PlannerConfig."""
    default = build_settings(default_values()).planner
    return {'default': default, 'join_paper': dataclasses.replace(default, join='paper'),
            'curvature': dataclasses.replace(default, join='paper', profile='curvature')}


def built_motion(config, pick, place):
    """Return the leg's path, speed cap and motion as its profile builds it (unchecked)."""
    path = plan_path(pick, place, config.pick_clearance, config.place_clearance, config.arc,
                     config.join, config.join_tolerance)
    cap = _check_reach_and_speed_cap(path, config)
    if config.profile == 'curvature':
        return path, cap, _curvature_motion(path, config.limits, config.curvature_r, cap)
    return path, cap, _optimal_motion(path, config.limits, cap)


def reference_peaks(motion, period):
    """Return the peak speed, acceleration and jerk norms on the reference samples (3,)."""
    law = motion.law
    bounds = (law.times if hasattr(law, 'times') else np.unique(law.bounds()[0]))
    bounds = bounds * motion.time_scale
    epsilon = 1e-9 * motion.duration
    t = np.unique(np.concatenate((
        _sample_times(motion.duration, period), np.maximum(bounds[1:-1] - epsilon, 0.0),
        np.minimum(bounds[1:-1] + epsilon, motion.duration))))
    pieces = np.searchsorted(bounds[1:-1], t, side='right')
    norms = _sampled(motion, t)[2]
    peaks = norms.max(axis=1)
    # The vertex of the parabola through each local maximum and its two neighbours, all in
    # one piece and evenly spaced (the grid's, not beside a sample just off a bound).
    h_1, h_2 = np.diff(t)[:-1], np.diff(t)[1:]
    even = ((pieces[:-2] == pieces[1:-1]) & (pieces[2:] == pieces[1:-1])
            & (np.minimum(h_1, h_2) >= 0.25 * np.maximum(h_1, h_2)))
    for row, values in enumerate(norms):
        d_1 = (values[1:-1] - values[:-2]) / h_1
        d_2 = (values[2:] - values[1:-1]) / h_2
        curvature = 2.0 * (d_2 - d_1) / (h_1 + h_2)
        slope = (d_1 * h_2 + d_2 * h_1) / (h_1 + h_2)
        use = even & (curvature < 0.0) & (d_1 >= 0.0) & (d_2 <= 0.0)
        if use.any():
            vertex = values[1:-1][use] - slope[use] ** 2 / (2.0 * curvature[use])
            peaks[row] = max(peaks[row], float(vertex.max()))
    return peaks


def leg_record(config, pick, place, period):
    """Return one leg's numbers (a dict), or None where the pair is refused."""
    try:
        path, cap, motion = built_motion(config, pick, place)
        timed = time_motion(path, config.limits, profile=config.profile,
                            r=config.curvature_r, speed_cap=cap)
        plan = plan_transfer(pick, place, config)
    except EllipathError:
        return None
    times = motion.sampled_states()[0]
    metrics = motion.metrics()
    sampled = np.array([metrics[f'peak_{key}'] for key in KEYS])
    reference = reference_peaks(motion, period)
    limits = config.limits
    caps = np.array([limits.max_speed, limits.max_accel, limits.max_jerk])
    trajectory = plan.joint_trajectory
    error = _interpolation_error(plan.motion, trajectory, config, per_segment=32)
    return {'samples': int(times.size),
            'difference': ((sampled - reference) / reference).tolist(),
            'final_ratio': (reference_peaks(timed, period) / caps).tolist(),
            'duration': float(trajectory.time_from_start[-1]),
            'timing_duration': float(timed.duration),
            'points': int(trajectory.time_from_start.size),
            'error_ratio': error / config.knot_tolerance}


def main(argv=None):
    """Run the comparison and print its summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--pairs', type=int, default=1000)
    parser.add_argument('--seed', type=int, default=11)
    parser.add_argument('--reference', type=float, default=1e-5,
                        help='reference grid period [s]')
    parser.add_argument('--legs', help='write one JSON line per leg to this file')
    args = parser.parse_args(argv)
    pairs = random_pairs(args.pairs, seed=args.seed)
    out = open(args.legs, 'w') if args.legs else None
    for name, config in kinds().items():
        records = []
        for index, (pick, place) in enumerate(pairs):
            record = leg_record(config, pick, place, args.reference)
            if record is None:
                continue
            records.append(record)
            if out:
                out.write(json.dumps({'kind': name, 'pair': index, **record}) + '\n')
        difference = np.array([record['difference'] for record in records])
        ratio = np.array([record['final_ratio'] for record in records])
        samples = np.array([record['samples'] for record in records])
        errors = np.array([record['error_ratio'] for record in records])
        sys.stdout.write(
            f'{name}: {len(records)} legs, samples per leg p50 {np.median(samples):.0f} '
            f'(min {samples.min()}, max {samples.max()})\n'
            '  sampled - reference, relative, lowest / highest: '
            + ', '.join(f'{key} {low:+.2e} / {high:+.2e}' for key, low, high in zip(
                KEYS, difference.min(axis=0), difference.max(axis=0))) + '\n'
            '  planned leg, reference peak / limit, largest: '
            + ', '.join(f'{key} {value:.7f}' for key, value in zip(KEYS, ratio.max(axis=0)))
            + f'\n  interpolation error / tolerance, largest: {errors.max():.4f}\n')
    if out:
        out.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
