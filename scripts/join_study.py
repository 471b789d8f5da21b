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
What limits the time-optimal cycle with the G2 join (issue 14, item 4): a study.

All durations are planned (time_motion, no JTC), as ratios to TOPP-RA's bound on the paper's
path without jerk limit or join cap (the bench's ``cycle`` ratio), for the bench's two cycles.

1. ``corners``: per cycle, the paper join (25 m/s² step) against the G2 join: speed at T1,
   dkappa/ds at T1 and the speed cap it sets through the normal jerk, the transition's peak
   curvature, and TOPP-RA's bound on the G2 path itself (what the geometry alone costs).
2. ``shapes``: the transition f(u) = u²(1-u)ⁿ(1/2 + p1 u + p2 u²) for several (n, p1, p2),
   each with spans from the closed-form horizontal bound and from the distance to the
   ellipse (the production rule, :func:`ellipath_ros.core.geometry.blend_arc`); the
   production shape is n = 4, p1 = p2 = 0, i.e. u²(1-u)⁴/2.
3. ``timing``: the same cycles with the scan's shares of the limits raised (is the join
   speed handling conservative?).
4. ``tolerance``: the production design at several ``join_tolerance``.
5. ``pairs``: on seeded random pairs (default settings), each shape's planned duration over
   that of the former production shape u²(1-u)⁴/2 (n = 4, p1 = p2 = 0).
6. ``requests``: whole requests (approach and transfer legs, ``plan_cycle``, default settings,
   the bench's seeded random pairs chained as the node serves them): each shape's planned
   cycle time over that with the former shape; the random legs of ``pairs`` miss the
   lopsided arcs of the approach legs, where a shape may trip the time-optimal scan.
7. ``entry``: the accelerations tried at G2 ends (``_END_ACCEL_SHARES`` of
   :mod:`ellipath_ros.core.optimal_profile`, chosen by probes): ratios per cycle, and on the
   seeded random pairs the planned duration over that with rest acceleration at the ends and
   the CPU time of the plans (``time.process_time``).

The shapes are swapped in by replacing the geometry module's ``_blend_shape`` and
``_BLEND_PEAK`` for the duration of one measurement, and clearing its cached distance grid
(which holds the shape's samples) on the way in and out (a study, not an API). Compiled
kernels freeze the functions and constants they call when they are compiled, so a swap
would reach only part of the code: the study runs the kernels as plain Python
(``NUMBA_DISABLE_JIT=1``, set by the script itself, which then takes minutes), where every
call reads the module's current values.

    PYTHONPATH=. python3 scripts/join_study.py [corners shapes timing tolerance pairs requests
                                                 entry]
"""

import contextlib
from dataclasses import replace
import math
import os
import sys
import time

from ellipath_ros.bench.cycle import CYCLES, topp_bound
from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core import arc_scan, geometry, optimal_profile
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.geometry import BlendedArc, PickPlacePath, plan_path
from ellipath_ros.core.limits import _JERK_MARGIN, CartesianLimits
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.settings import default_values
from ellipath_ros.core.timing import time_motion
from ellipath_ros.parameters import build_settings
import numpy as np
from numpy.polynomial import Polynomial

LIMITS = replace(CartesianLimits(), max_accel_jump=25.0)
CLEARANCE = 0.025
# (n, p1, p2) of the shapes u²(1-u)ⁿ(1/2 + p1 u + p2 u²) studied; (4, 0, 0) is the production
# shape.
SHAPES = ((3, 0.0, 0.0), (4, 0.0, 0.0), (4, 1.0, 0.0), (5, 0.5, 0.0), (5, 1.0, 0.0),
          (6, 0.5, 0.0), (6, 1.0, 0.0), (6, 1.25, 0.0), (6, 1.5, 0.0), (7, 1.5, 0.0),
          (8, 2.0, 0.0), (10, 3.0, 0.0))
FORMER_SHAPE = (4, 0.0, 0.0)
# The pairs study: how many, the seed, and the box they are drawn from (a cylinder of
# PAIR_RADIUS around the axis, heights in PAIR_HEIGHTS) [m].
PAIR_COUNT = 120
PAIR_SEED = 7
PAIR_RADIUS = 0.2
PAIR_HEIGHTS = (-0.9, -0.75)
# The requests study: how many of the bench's seeded random pairs, and the shapes compared.
REQUEST_COUNT = 150
REQUEST_SHAPES = ((4, 0.0, 0.0), (5, 0.5, 0.0), (6, 1.0, 0.0), (6, 1.25, 0.0))
# Shares of the scan (arc_scan.py, optimal_profile.py) raised one at a time, then all at once.
TIMING_VARIANTS = ({}, {'_NORMAL_JERK_SHARE': 0.98}, {'_CEILING_SHARE': 0.98},
                   {'_VALLEY_SHARE': 0.98}, {'_END_RETRY_FACTOR': 0.97, '_END_TRIES': 100},
                   {'_NORMAL_JERK_SHARE': 0.98, '_CEILING_SHARE': 0.98, '_VALLEY_SHARE': 0.98,
                    '_END_RETRY_FACTOR': 0.97, '_END_TRIES': 100})
TOLERANCES = (2.5e-4, 5e-4, 1e-3, 2e-3)
# Accelerations tried at G2 ends, as shares of max_accel (the first is rest acceleration).
ENTRY_VARIANTS = ((0.0,), (0.0, -0.1), (0.0, -0.15), (0.0, -0.2), (0.0, -0.25), (0.0, -0.3),
                  (0.0, -0.1, -0.2), (0.0, -0.1, -0.2, -0.3), (-0.2,))


def family_shape(n, p1, p2):
    """Return (shape function like geometry._blend_shape, largest |f|, largest |f'| on [0, 1])."""
    f = Polynomial([0.0, 0.0, 1.0]) * Polynomial([1.0, -1.0]) ** n * Polynomial([0.5, p1, p2])
    derivatives = [f, f.deriv(1), f.deriv(2), f.deriv(3)]
    u = np.linspace(0.0, 1.0, 100001)
    peak, slope = (float(np.abs(d(u)).max()) * (1.0 + 1e-6) for d in derivatives[:2])
    return (lambda u: tuple(d(u) for d in derivatives)), peak, slope


@contextlib.contextmanager
def shape_of(n, p1, p2):
    """Use the shape (n, p1, p2) in the geometry module for the duration of the block."""
    shape, peak, slope = family_shape(n, p1, p2)
    # The distance grid caches the shape's samples: it must follow the swap both ways.
    geometry._distance_grid.cache_clear()
    try:
        with patched(geometry, _blend_shape=shape, _BLEND_PEAK=peak, _BLEND_SLOPE_BOUND=slope):
            yield
    finally:
        geometry._distance_grid.cache_clear()


@contextlib.contextmanager
def patched(module, **values):
    """Set module attributes for the duration of the block (those the module has)."""
    saved = {name: getattr(module, name) for name in values if hasattr(module, name)}
    for name in saved:
        setattr(module, name, values[name])
    try:
        yield sorted(saved)
    finally:
        for name, value in saved.items():
            setattr(module, name, value)


def paper_path(case):
    """Return the paper-join path of a bench cycle."""
    _, pick, place, policy = case
    return plan_path(pick, place, CLEARANCE, CLEARANCE, policy, 'paper')


def with_bend(paper, bend):
    """Return the paper's path with ``bend`` between T1 and T2 (join g2)."""
    return PickPlacePath(paper.pick, paper.place, paper.tangent_1, paper.tangent_2, paper.arc,
                         paper.direction, np.array([CLEARANCE, bend.length, CLEARANCE]),
                         bend, 'g2')


def g2_path(case, tolerance=geometry.DEFAULT_JOIN_TOLERANCE, horizontal=False):
    """Return a bench cycle's G2 path with the current shape (see :func:`bend_of`)."""
    paper = paper_path(case)
    return with_bend(paper, bend_of(paper, tolerance, horizontal))


def bend_of(paper, tolerance=geometry.DEFAULT_JOIN_TOLERANCE, horizontal=False):
    """Return the bend of ``paper``'s ellipse, spans by distance or by horizontal bound."""
    arc = paper.arc
    if not horizontal:
        return geometry.blend_arc(arc, tolerance)
    span = math.sqrt(tolerance / (geometry._BLEND_PEAK * arc.l))
    t_apex = math.atan2(arc.k, arc.h)
    caps = (geometry._BLEND_APEX_SHARE * (math.pi - t_apex), geometry._BLEND_APEX_SHARE * t_apex)
    return BlendedArc(arc, *(min(span, cap, geometry._BLEND_MAX_SPAN) for cap in caps))


BOUNDS = {}


def ratio(case, path):
    """Return the planned duration on ``path`` over TOPP-RA's bound on the paper path."""
    if case[0] not in BOUNDS:
        BOUNDS[case[0]] = topp_bound(paper_path(case), LIMITS, join_cap=False)
    return time_motion(path, LIMITS).duration / BOUNDS[case[0]]


def corner_figures(path):
    """Return (speed at T1, dkappa/ds at T1, its speed cap, peak kappa / kappa_T) of a path."""
    motion = time_motion(path, LIMITS)
    t = np.linspace(0.0, motion.duration, 20001)
    s, v = motion.path_state(t)[:2]
    s_t1 = path.segment_ends[1]
    speed_t1 = float(np.interp(s_t1, s, v))
    near = s_t1 + np.linspace(0.0, 0.03, 3001)
    samples = path.at_lengths(near)
    kappa = np.linalg.norm(samples.curvature, axis=1)
    kappa_s = float(np.linalg.norm(samples.curvature_rate[1]))
    share = optimal_profile._CEILING_SHARE * _JERK_MARGIN * LIMITS.max_jerk
    cap = (share / kappa_s) ** (1.0 / 3.0) if kappa_s > 0.0 else math.inf
    return speed_t1, kappa_s, cap, float(kappa.max()) / path.arc.curvature_and_rate(
        np.array([math.pi]))[0][0]


def corners():
    """Print what limits each cycle at its corners."""
    print('## corners: paper join (25 m/s² step) against g2 (planned)')
    for case in CYCLES:
        paper, bent = paper_path(case), g2_path(case)
        bound_g2 = topp_bound(bent, LIMITS, join_cap=False)
        name = case[0]
        print(f'{name}: rho_T {1e3 * paper.arc.end_radius:.2f} mm; TOPP-RA bound on the G2 '
              f'path / on the paper path {bound_g2 / topp_bound(paper, LIMITS, False):.4f}')
        for label, path in (('paper, 25 m/s² step', paper), ('g2', bent)):
            speed, kappa_s, cap, peak = corner_figures(path)
            print(f'  {label:20s} ratio {ratio(case, path):.4f}  v(T1) {speed:.3f} m/s  '
                  f'dkappa/ds(T1) {kappa_s:8.0f} 1/m²  normal-jerk cap at T1 {cap:.3f} m/s  '
                  f'peak kappa / kappa_T {peak:.2f}')


def shapes():
    """Print the ratios of the shape family, spans by horizontal bound and by distance."""
    print('## shapes: f = u²(1-u)ⁿ(1/2 + p1 u + p2 u²), ratio per cycle (planned); '
          "f'''(0) = 6 p1 - 3 n")
    for n, p1, p2 in SHAPES:
        row = []
        with shape_of(n, p1, p2):
            for case in CYCLES:
                by_offset, by_distance = g2_path(case, horizontal=True), g2_path(case)
                row.append(f'{ratio(case, by_offset):.4f} / {ratio(case, by_distance):.4f} '
                           f'(span {by_distance.bend.span_1:.3f})')
        print(f'  n {n:2d} p1 {p1:+.2f} p2 {p2:+.2f}: horizontal bound / distance: '
              + ' | '.join(row))


def timing_variants():
    """Print the production design's ratios with the scan's shares raised."""
    print('## timing: shares of the limits in the scan raised (planned ratios, g2)')
    for variant in TIMING_VARIANTS:
        with patched(optimal_profile, **variant) as names, patched(arc_scan, **variant) as more:
            row = [f'{ratio(case, g2_path(case)):.4f}' for case in CYCLES]
        names = sorted(names + more)
        described = ', '.join(f'{name} {variant[name]}' for name in names) or 'as shipped'
        print(f"  {described}: {' | '.join(row)}")


def tolerances():
    """Print the production design's ratios at several join tolerances."""
    print('## tolerance: production design (planned ratios, g2)')
    for tolerance in TOLERANCES:
        row = [f'{ratio(case, g2_path(case, tolerance)):.4f}' for case in CYCLES]
        print(f"  join_tolerance {1e3 * tolerance:.2f} mm: {' | '.join(row)}")


def random_papers():
    """Return the paper-join paths of ``PAIR_COUNT`` seeded random pairs (default arc rule)."""
    rng = np.random.default_rng(PAIR_SEED)
    papers = []
    while len(papers) < PAIR_COUNT:
        ends = []
        for _ in range(2):
            radius, angle = PAIR_RADIUS * math.sqrt(rng.uniform()), rng.uniform(0.0, 2 * math.pi)
            ends.append((radius * math.cos(angle), radius * math.sin(angle),
                         rng.uniform(*PAIR_HEIGHTS)))
        try:
            papers.append(plan_path(ends[0], ends[1], CLEARANCE, CLEARANCE))
        except geometry.DegenerateGeometryError:
            continue
    return papers


def pairs():
    """Print each shape's planned durations on random pairs over the design before."""
    print(f'## pairs: {PAIR_COUNT} seeded random pairs (seed {PAIR_SEED}), planned duration over '
          f'that with the former shape {FORMER_SHAPE}')
    limits = CartesianLimits()
    papers = random_papers()

    def durations():
        return np.array([time_motion(with_bend(paper, bend_of(paper)), limits).duration
                         for paper in papers])

    with shape_of(*FORMER_SHAPE):
        before = durations()
    for n, p1, p2 in SHAPES:
        with shape_of(n, p1, p2):
            ratios = durations() / before
        print(f'  n {n:2d} p1 {p1:+.2f} p2 {p2:+.2f}: mean {ratios.mean():.4f} median '
              f'{np.median(ratios):.4f} max {ratios.max():.3f}; faster on '
              f'{np.mean(ratios < 0.9995):.0%}, slower on {np.mean(ratios > 1.0005):.0%}')


def entries():
    """Print the cycles' ratios and the pairs' durations per set of G2 end accelerations."""
    print(f'## entry: accelerations tried at G2 ends (shares of max_accel), ratio per cycle; '
          f'{PAIR_COUNT} seeded random pairs: planned duration over that at rest acceleration, '
          'CPU time of their plans')
    limits = CartesianLimits()
    bent = [with_bend(paper, bend_of(paper)) for paper in random_papers()]
    at_rest = None
    for shares in ENTRY_VARIANTS:
        with patched(optimal_profile, _END_ACCEL_SHARES=shares):
            row = [f'{ratio(case, g2_path(case)):.4f}' for case in CYCLES]
            start = time.process_time()
            durations = np.array([time_motion(path, limits).duration for path in bent])
            cpu = time.process_time() - start
        at_rest = durations if at_rest is None else at_rest
        ratios = durations / at_rest
        print(f"  {', '.join(f'{share:+.2f}' for share in shares):28s} {' | '.join(row)};  "
              f'pairs mean {ratios.mean():.4f} max {ratios.max():.4f}, faster on '
              f'{np.mean(ratios < 0.999):.0%}, slower on {np.mean(ratios > 1.001):.0%}; '
              f'CPU {cpu:.2f} s')


def requests():
    """Print each shape's planned cycle times of whole random requests over the former's."""
    print(f'## requests: {REQUEST_COUNT} seeded random requests (plan_cycle, default settings), '
          f'planned cycle time over that with the former shape {FORMER_SHAPE}')
    settings = build_settings(default_values())

    def cycle_times():
        start = np.asarray(settings.home_position, dtype=float)
        times = []
        for pick, place in random_pairs(REQUEST_COUNT):
            try:
                plan = plan_cycle(start, pick, place, settings.planner,
                                  pick_dwell=settings.pick_dwell,
                                  place_dwell=settings.place_dwell)
            except EllipathError:
                times.append(math.nan)
                continue
            start = plan.end_position
            times.append(float(plan.joint_trajectory.time_from_start[-1]))
        return np.array(times)

    with shape_of(*FORMER_SHAPE):
        before = cycle_times()
    for n, p1, p2 in REQUEST_SHAPES:
        with shape_of(n, p1, p2):
            times = cycle_times()
        kept = ~(np.isnan(before) | np.isnan(times))
        ratios = times[kept] / before[kept]
        total = times[kept].sum() / before[kept].sum()
        print(f'  n {n:2d} p1 {p1:+.2f} p2 {p2:+.2f}: total {total:.4f}'
              f' median {np.median(ratios):.4f} max {ratios.max():.3f}; faster on '
              f'{np.mean(ratios < 0.9995):.0%}, slower on {np.mean(ratios > 1.0005):.0%}, '
              f'over 1.05 on {np.sum(ratios > 1.05)} of {kept.sum()}')


STUDIES = {'corners': corners, 'shapes': shapes, 'timing': timing_variants,
           'tolerance': tolerances, 'pairs': pairs, 'requests': requests, 'entry': entries}


def main(argv):
    if os.environ.get('NUMBA_DISABLE_JIT') != '1':
        # Start again with plain-Python kernels, before any is compiled (see the docstring).
        os.execve(sys.executable, [sys.executable, *sys.argv],
                  {**os.environ, 'NUMBA_DISABLE_JIT': '1'})
    print('cycles: ' + ' | '.join(case[0] for case in CYCLES))
    for name in argv or STUDIES:
        STUDIES[name]()
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
