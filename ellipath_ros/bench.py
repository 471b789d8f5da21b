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
Benchmark of the timing profiles against the time-optimal bound without jerk limit.

For the paper's example and the 25-305-25 mm cycle it times the ``g2`` join
with the ``time_optimal`` profile, and the paper's path (``join`` paper) at two
values of ``max_accel_jump`` with the ``curvature`` profile (the paper's) and
the ``time_optimal`` one. Each is compared with the bound that TOPP-RA computes
on the paper's path with the same speed and acceleration limits, without the
jerk limit and without a bound on the acceleration step at T1/T2 (``bound``);
the paper-join rows are also compared with the bound that keeps their step
(``ratio to step bound``). No jerk-limited motion can beat these bounds (the
g2 path is within 0.5 mm of the paper's, its bound within 0.1 %). TOPP-RA is an optional
dependency (the ``bench`` extra); the planner itself never imports it.
"""

import math
import statistics
import time

import numpy as np

from .core.geometry import ArcPolicy, plan_path
from .core.timing import CartesianLimits, time_motion

# (name, pick, place, arc policy) of the benchmark's cycles [m].
CYCLES = (
    ("paper's example", (0.0, 0.0, -0.8), (0.3, 0.0, -0.75), ArcPolicy()),
    ('25-305-25 mm', (0.0, 0.0, -0.8), (0.305, 0.0, -0.8),
     ArcPolicy('apex_clearance', apex_clearance=0.025)),
)
MAX_ACCEL_JUMPS = (25.0, 5.0)
# A step bound this high never binds: the bound without a join constraint.
NO_STEP_BOUND = 1e4
# TOPP-RA discretisation: grid points along the path, facets of the polygon that stands in for
# the circle |acceleration| <= max_accel (circumscribed: the bound stays a lower bound).
BOUND_GRID_POINTS = 2000
BOUND_FACETS = 64
COLUMNS = (
    ('cycle', 'cycle', '{}'),
    ('join', 'join', '{}'),
    ('max_accel_jump', 'max accel jump [m/s²]', '{:g}'),
    ('profile', 'profile', '{}'),
    ('duration', 'duration [s]', '{:.4f}'),
    ('ratio', 'ratio to bound', '{:.3f}'),
    ('step_ratio', 'ratio to step bound', '{:.3f}'),
    ('peak_speed', 'planned peak speed [m/s]', '{:.2f}'),
    ('peak_accel', 'planned peak accel [m/s²]', '{:.1f}'),
    ('peak_jerk', 'planned peak jerk [m/s³]', '{:.0f}'),
    ('plan_ms', 'planning [ms]', '{:.1f}'),
)


def _toppra():
    """Import TOPP-RA or say how to get it."""
    try:
        import toppra
        import toppra.algorithm
        import toppra.constraint
        import toppra.interpolator
    except ImportError:
        raise ImportError('TOPP-RA is missing; install the bench extra: '
                          'pip install .[bench]') from None
    return toppra


def topp_bound(path, limits):
    """
    Return the time-optimal duration [s] along ``path`` without the jerk limit (TOPP-RA).

    Constraints: s' <= max_speed, |acceleration| <= max_accel (as a
    circumscribed polygon of ``BOUND_FACETS`` sides in the path's plane) and,
    at T1 and T2, s'**2 / rho_T <= max_accel_jump. From rest to rest.

    Raises
    ------
    ImportError
        TOPP-RA is not installed.

    """
    toppra = _toppra()

    class _Path(toppra.interpolator.AbstractGeometricPath):
        def __call__(self, positions, order=0):
            samples = path.evaluate(np.atleast_1d(positions))
            return (samples.position, samples.tangent, samples.curvature)[order]

        @property
        def dof(self):
            return 3

        @property
        def path_interval(self):
            return np.array([0.0, path.length])

    class _Limits(toppra.constraint.LinearConstraint):
        def __init__(self):
            super().__init__()
            self.identical = True

        def get_dof(self):
            return 3

        def compute_constraint_params(self, _, grid, *args, **kwargs):
            samples = path.evaluate(grid)
            # Acceleration in the path's plane: (along u, vertical) = p' s'' + p'' s'**2.
            plane = np.stack((path.direction, np.array([0.0, 0.0, 1.0])))
            angles = 2.0 * math.pi * np.arange(BOUND_FACETS) / BOUND_FACETS
            facets = np.stack((np.cos(angles), np.sin(angles)), axis=1)
            speed_squared = np.column_stack((np.zeros(grid.size),
                                             np.full(grid.size, limits.max_speed ** 2)))
            if path.arc is not None:
                for s_join in path.segment_ends[1:3]:
                    index = int(np.argmin(np.abs(grid - s_join)))
                    speed_squared[index, 1] = min(
                        speed_squared[index, 1], limits.max_accel_jump * path.arc.end_radius)
            return (samples.tangent @ plane.T, samples.curvature @ plane.T,
                    np.zeros((grid.size, 2)), facets, np.full(BOUND_FACETS, limits.max_accel),
                    None, speed_squared)

    grid = np.unique(np.concatenate((np.linspace(0.0, path.length, BOUND_GRID_POINTS),
                                     path.segment_ends)))
    solver = toppra.algorithm.TOPPRA([_Limits()], _Path(), gridpoints=grid,
                                     solver_wrapper='seidel')
    _, speed, _ = solver.compute_parameterization(0.0, 0.0)
    if speed is None:
        raise RuntimeError('TOPP-RA found no parameterisation')
    return float(np.sum(2.0 * np.diff(grid) / (speed[1:] + speed[:-1])))


def _median_ms(function, repeats):
    """Return (result, median wall time [ms]) of ``repeats`` calls after one warm-up call."""
    result = function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return result, 1e3 * statistics.median(times)


def run_benchmark(repeats=20, max_accel_jumps=MAX_ACCEL_JUMPS, limits=None):
    """
    Time the g2 join and both profiles on the paper's path; compare with TOPP-RA.

    Parameters
    ----------
    repeats : int
        Plans per case for the median planning time, >= 1.
    max_accel_jumps : sequence of float
        Values of ``max_accel_jump`` to run [m/s**2].
    limits : CartesianLimits, optional
        Speed, acceleration and jerk limits (defaults); ``max_accel_jump`` is
        taken from ``max_accel_jumps``.

    Returns
    -------
    list of dict
        Per cycle: the bound without a step constraint, the g2 join, then per
        jump value the bound with that step and both profiles on the paper's
        path; keys as in ``COLUMNS`` (missing ones print as '-'); bound rows
        have no peaks, their planning time is TOPP-RA's.

    Raises
    ------
    ImportError
        TOPP-RA is not installed (``pip install .[bench]``).

    """
    _toppra()
    repeats = max(int(repeats), 1)
    base = limits or CartesianLimits()
    rows = []
    for name, pick, place, policy in CYCLES:
        paper = plan_path(pick, place, policy=policy, join='paper')
        free = CartesianLimits(base.max_speed, base.max_accel, base.max_jerk, NO_STEP_BOUND)
        bound, bound_ms = _median_ms(lambda: topp_bound(paper, free), max(repeats // 10, 1))
        rows.append({'cycle': name, 'join': 'paper', 'profile': 'TOPP-RA bound',
                     'duration': bound, 'ratio': 1.0, 'plan_ms': bound_ms})
        g2 = plan_path(pick, place, policy=policy, join='g2')
        rows.append(_timed_row(name, g2, free, 'time_optimal', bound, None, repeats))
        for jump in max_accel_jumps:
            case = CartesianLimits(base.max_speed, base.max_accel, base.max_jerk, jump)
            step_bound, step_ms = _median_ms(lambda: topp_bound(paper, case),
                                             max(repeats // 10, 1))
            rows.append({'cycle': name, 'join': 'paper', 'max_accel_jump': jump,
                         'profile': 'TOPP-RA step bound', 'duration': step_bound,
                         'ratio': step_bound / bound, 'step_ratio': 1.0, 'plan_ms': step_ms})
            for profile in ('time_optimal', 'curvature'):
                row = _timed_row(name, paper, case, profile, bound, step_bound, repeats)
                row['max_accel_jump'] = jump
                rows.append(row)
    return rows


def _timed_row(name, path, limits, profile, bound, step_bound, repeats):
    """Time ``path`` with ``profile``; return its row (ratios to the bounds given)."""
    motion, plan_ms = _median_ms(lambda: time_motion(path, limits, profile=profile), repeats)
    metrics = motion.metrics()
    return {'cycle': name, 'join': path.join, 'profile': profile,
            'duration': motion.duration, 'ratio': motion.duration / bound,
            'step_ratio': None if step_bound is None else motion.duration / step_bound,
            'peak_speed': metrics['peak_speed'], 'peak_accel': metrics['peak_accel'],
            'peak_jerk': metrics['peak_jerk'], 'plan_ms': plan_ms}


def format_table(rows):
    """Return ``rows`` (from :func:`run_benchmark`) as a Markdown table, one line per row."""
    lines = ['| ' + ' | '.join(title for _, title, _ in COLUMNS) + ' |',
             '|' + '|'.join('---' for _ in COLUMNS) + '|']
    for row in rows:
        cells = ['-' if row.get(key) is None else form.format(row[key])
                 for key, _, form in COLUMNS]
        lines.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)
