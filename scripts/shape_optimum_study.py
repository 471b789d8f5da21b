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
The jerk-limited optimum on other G2 transition shapes (issue 14, item 4): a study.

``optimum_study.py`` computed the jerk-limited time optimum on the shipped G2 path
(f(u) = u²(1-u)⁴/2 within ``join_tolerance`` 0.5 mm): 1.153 and 1.149 times TOPP-RA's bound,
against the paper join's 1.128 and 1.123 (the target). This study computes the same optimum
(``optimum_study.optimum``: direct transcription, SLP with HiGHS, re-checked off the grid) on
the transitions f(u) = u²(1-u)ⁿ(1/2 + p1 u + p2 u²) of ``join_study.py``, each with the
longest spans within the tolerance (the production rule, ``geometry.blend_arc``), on the
bench's two cycles. Per shape and cycle it prints the spans (parameter width and arc length of
each transition), the largest distance of the bent path from the paper's path (measured here
independently of the production's bound: 4,001 samples per transition, the nearest point of
the ellipse by a dense search and Newton steps, or of the vertical segment if nearer), the
scan's ratio and the optimum's ratio (planned figures), and the optimum's speed at T1.

The shapes are swapped in as in ``join_study.py`` (``shape_of``; the kernels run as plain
Python, ``NUMBA_DISABLE_JIT=1``, set by the script itself). Limits as in
``optimum_study.py``: the bench's, scaled by the planner's margins for the optimum, as given
to the scan. Each optimum takes a few CPU minutes.

    PYTHONPATH=. python3 scripts/shape_optimum_study.py [n:p1:p2 ...] [--tolerance METRES]
                                                        [--cycle INDEX]

Without shapes it runs ``SHAPES``; ``--tolerance`` sets ``join_tolerance`` (default 0.5 mm),
``--cycle`` one of the bench's cycles (0 the paper's example, 1 25-305-25 mm; both by default).
"""

import math
import os
import sys

from ellipath_ros.bench.cycle import CYCLES
from ellipath_ros.core.geometry import DEFAULT_JOIN_TOLERANCE
import join_study  # noqa: I100 (sibling scripts: scripts/ is not a package)
import numpy as np
import optimum_study

# (n, p1, p2): the best shapes of join_study's scan at 0.5 mm, then longer tails.
SHAPES = ((6, 1.25, 0.0), (6, 1.0, 0.0), (5, 0.5, 0.0), (8, 2.0, 0.0), (7, 1.5, 0.0),
          (10, 3.0, 0.0))
# Samples per transition for the distance, and of the ellipse's parameter searched around each.
DISTANCE_SAMPLES = 4001
SEARCH_SAMPLES = 2001
NEWTON_STEPS = 4


def ellipse_points(arc, t):
    """Return the paper's ellipse (l cos t, h cos t + k sin t) and its derivative, (N, 2)."""
    cos_t, sin_t = np.cos(t), np.sin(t)
    return (np.stack((arc.l * cos_t, arc.h * cos_t + arc.k * sin_t), axis=-1),
            np.stack((-arc.l * sin_t, arc.k * cos_t - arc.h * sin_t), axis=-1))


def distance_to_paper(path, at_t1):
    """
    Return the largest distance of a transition from the paper's path [m] (dense check).

    Samples of the transition (the bend's own points, paper frame); for each, the nearest
    point of the paper's ellipse on t in [0, pi] (a search over the transition's parameter
    range widened threefold, then Newton steps on (P(t) - Q) . P'(t) = 0), or of the vertical
    segment below T1 or T2 if that is nearer.
    """
    bend, arc = path.bend, path.arc
    span = bend.span_1 if at_t1 else bend.span_2
    u = np.linspace(0.0, 1.0, DISTANCE_SAMPLES)
    t = math.pi - span * u if at_t1 else span * u
    bent = bend.point(t)
    if at_t1:
        low, high = max(math.pi - 3.0 * span, 0.0), math.pi
    else:
        low, high = 0.0, min(3.0 * span, math.pi)
    grid = np.linspace(low, high, SEARCH_SAMPLES)
    on_grid, _ = ellipse_points(arc, grid)
    nearest = np.empty(t.size)
    for start in range(0, t.size, 500):
        block = bent[start:start + 500]
        gaps = np.linalg.norm(block[:, None, :] - on_grid[None, :, :], axis=2)
        nearest[start:start + 500] = grid[np.argmin(gaps, axis=1)]
    for _ in range(NEWTON_STEPS):
        point, slope = ellipse_points(arc, nearest)
        gap = point - bent
        # d/dt of gap . P' is |P'|² + gap . P'' with P'' = -P.
        rate = np.sum(slope * slope, axis=1) - np.sum(gap * point, axis=1)
        nearest = np.clip(nearest - np.sum(gap * slope, axis=1) / rate, 0.0, math.pi)
    to_ellipse = np.linalg.norm(ellipse_points(arc, nearest)[0] - bent, axis=1)
    # The vertical segment below the end (paper frame: x = P_x(end), y down to the clearance).
    end = ellipse_points(arc, np.array([math.pi if at_t1 else 0.0]))[0][0]
    clearance = path.segment_lengths[0 if at_t1 else 2]
    below = np.clip(bent[:, 1], end[1] - clearance, end[1])
    to_line = np.hypot(bent[:, 0] - end[0], bent[:, 1] - below)
    return float(np.minimum(to_ellipse, to_line).max())


def shape_row(shape, tolerance, cases=CYCLES, log=print):
    """Print the spans, distances, scan and optimum ratios of one shape on ``cases``."""
    limits, plan_limits = optimum_study.study_limits(False)
    with join_study.shape_of(*shape):
        for case in cases:
            path = optimum_study.cycle_path(case, 'g2', tolerance)
            bounds = optimum_study.regions(path)
            distances = [distance_to_paper(path, at_t1) for at_t1 in (True, False)]
            motion, _, _, check = optimum_study.optimum(path, limits, plan_limits,
                                                        log=lambda _: None)
            bound = optimum_study.bound_of(case)
            n, p1, p2 = shape
            log(f'  n {n:2d} p1 {p1:+.3f} p2 {p2:+.3f} | {case[0]} | spans '
                f'{path.bend.span_1:.4f} / {path.bend.span_2:.4f} rad, '
                f'{1e3 * bounds[1]:.2f} / {1e3 * (bounds[3] - bounds[2]):.2f} mm | distance '
                f'{1e3 * distances[0]:.4f} / {1e3 * distances[1]:.4f} mm | scan '
                f'{motion.duration / bound:.4f} | optimum {check["duration"] / bound:.4f} | '
                f'optimum v(T1) {check["speed"][0]:.3f} m/s | checked peaks: speed '
                f'{check["fd_speed"] / limits.max_speed:.4f}, accel '
                f'{check["fd_accel"] / limits.max_accel:.4f}, jerk '
                f'{max(check["fd_jerk"], check["line_jerk"]) / limits.max_jerk:.4f} of the '
                'margin-scaled limits', flush=True)


def parse_shape(text):
    """Return (n, p1, p2) from 'n:p1:p2' (p2 optional)."""
    parts = text.split(':')
    if not 2 <= len(parts) <= 3:
        raise SystemExit(f'shape: expected n:p1[:p2], got {text!r}')
    return (int(parts[0]), float(parts[1]), float(parts[2]) if len(parts) == 3 else 0.0)


def main(argv):
    if os.environ.get('NUMBA_DISABLE_JIT') != '1':
        # Start again with plain-Python kernels, before any is compiled (join_study.py).
        os.execve(sys.executable, [sys.executable, *sys.argv],
                  {**os.environ, 'NUMBA_DISABLE_JIT': '1'})
    options = {'--tolerance': DEFAULT_JOIN_TOLERANCE, '--cycle': None}
    for name in options:
        if name in argv:
            index = argv.index(name)
            options[name] = float(argv[index + 1])
            argv = argv[:index] + argv[index + 2:]
    tolerance = options['--tolerance']
    cases = CYCLES if options['--cycle'] is None else [CYCLES[int(options['--cycle'])]]
    shapes = [parse_shape(text) for text in argv] or list(SHAPES)
    print(f'join_tolerance {1e3 * tolerance:g} mm; shape | cycle | spans at T1 / T2 | largest '
          'distance from the paper path | scan ratio | optimum ratio (planned, to the bound)',
          flush=True)
    for shape in shapes:
        shape_row(shape, tolerance, cases)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
