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
The cycle benchmarks: durations against TOPP-RA's bound, and picks per minute.

For the paper's example and the 25-305-25 mm cycle, at two values of
``max_accel_jump``, the planner times the paper's path (``join`` paper) with
the ``time_optimal`` and the ``curvature`` (the paper's) profiles, and the
curvature-continuous path (``join`` g2, which has no acceleration step to cap)
with ``time_optimal``. Each is compared with the bound that TOPP-RA computes
on the paper's path with the same Cartesian limits, without the jerk limit and
without the cap at the joins: no motion along that path can beat it (the g2
path lies within 0.5 mm of it). Joint limits are lifted to the top of their
ranges so that the Cartesian limits alone set the durations. All durations are
*planned*; JTC executes the published points on the same time line.

Picks per minute: the 25-305-25 mm cycle repeated pick -> place -> pick with
two 35 ms dwells, at the node's default limits and at fast limits with the
joint limits lifted, beside the figure ABB quotes for its IRB 360.

TOPP-RA is an optional dependency (the ``bench`` extra); the planner itself
never imports it.
"""

from dataclasses import replace
import math

import numpy as np

from ..core.geometry import ArcPolicy, plan_path
from ..core.kinematics import JointLimits
from ..core.limits import CartesianLimits
from ..core.planner import plan_cycle, plan_transfer, PlannerConfig

# (name, pick, place, arc policy) of the benchmark's cycles [m].
CYCLES = (
    ("paper's example", (0.0, 0.0, -0.8), (0.3, 0.0, -0.75), ArcPolicy()),
    ('25-305-25 mm', (0.0, 0.0, -0.8), (0.305, 0.0, -0.8),
     ArcPolicy('apex_clearance', apex_clearance=0.025)),
)
MAX_ACCEL_JUMPS = (5.0, 25.0)
PROFILES = ('time_optimal', 'curvature')
# TOPP-RA discretisation: grid points along the path, facets of the polygon that stands in for
# the circle |acceleration| <= max_accel (circumscribed: the bound stays a lower bound).
BOUND_GRID_POINTS = 2000
BOUND_FACETS = 64
# The joint limits at the top of their parameter ranges: only the Cartesian limits bind.
LIFTED_JOINT_LIMITS = JointLimits(max_velocity=1000.0, max_acceleration=1e5)
# How the line meets the ellipse at T1/T2; 'g2' exists once the config has a 'join' field.
JOINS = ('paper', 'g2')
# Picks per minute: the 25-305-25 mm cycle, a dwell at the pick and one at the place [s].
PICK_PLACE_DWELL = 0.035
FAST_LIMITS = CartesianLimits(max_speed=10.0, max_accel=100.0, max_jerk=20000.0)
# ABB's quoted figure for the IRB 360 FlexPicker on the 25-305-25 mm cycle (vendor's data
# sheet, 0.1 to 1 kg payload), not a measurement of ours.
ABB_IRB360 = {'robot': 'ABB IRB 360', 'picks_per_min': [150, 160], 'payload_kg': [0.1, 1.0],
              'source': "vendor's quoted figure, 25-305-25 mm cycle"}


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


def topp_bound(path, limits, join_cap=True):
    """
    Return the time-optimal duration [s] along ``path`` without the jerk limit (TOPP-RA).

    Constraints: s' <= max_speed, |acceleration| <= max_accel (as a
    circumscribed polygon of ``BOUND_FACETS`` sides in the path's plane) and,
    with ``join_cap``, at T1 and T2, s'**2 / rho_T <= max_accel_jump. From
    rest to rest. Without ``join_cap`` it bounds every motion along the path
    whatever happens at the joins.

    Raises
    ------
    ImportError
        TOPP-RA is not installed.

    """
    toppra = _toppra()

    class _Path(toppra.interpolator.AbstractGeometricPath):
        def __call__(self, positions, order=0):
            samples = path.at_lengths(np.atleast_1d(positions))
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
            samples = path.at_lengths(grid)
            # Acceleration in the path's plane: (along u, vertical) = p' s'' + p'' s'**2.
            plane = np.stack((path.direction, np.array([0.0, 0.0, 1.0])))
            angles = 2.0 * math.pi * np.arange(BOUND_FACETS) / BOUND_FACETS
            facets = np.stack((np.cos(angles), np.sin(angles)), axis=1)
            speed_squared = np.column_stack((np.zeros(grid.size),
                                             np.full(grid.size, limits.max_speed ** 2)))
            if join_cap and path.arc is not None:
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


def joins_of(config):
    """Return the joins to bench: both when the config knows ``join``, else the paper's."""
    return JOINS if hasattr(config, 'join') else ('paper',)


def with_join(config, join):
    """Return ``config`` with ``join`` set (unchanged when the config has no such field)."""
    return replace(config, join=join) if hasattr(config, 'join') else config


def cycle_rows(base=None, profiles=PROFILES, max_accel_jumps=MAX_ACCEL_JUMPS, progress=None):
    """
    Plan both cycles for every join, profile and jump value; compare with TOPP-RA.

    Parameters
    ----------
    base : PlannerConfig, optional
        Limits and settings to start from (defaults); its joint limits are lifted, its arc
        policy and ``max_accel_jump`` are the cycle's.
    profiles : sequence of str
        Profiles to plan.
    max_accel_jumps : sequence of float
        Values of ``max_accel_jump`` [m/s**2].
    progress : callable, optional
        Called with (rows done, rows in all).

    Returns
    -------
    list of dict
        ``case``, ``profile``, ``join``, ``max_accel_jump``, ``duration_s`` (planned),
        ``topp_ra_bound_s`` (no jerk limit, no join cap), ``ratio_to_bound``, the planned
        peaks ``peak_speed``, ``peak_accel``, ``peak_jerk`` and, for the paper's join,
        ``topp_ra_bound_join_capped_s`` (the bound with the same cap at T1/T2).

    Raises
    ------
    ImportError
        TOPP-RA is not installed (``pip install .[bench]``).

    """
    _toppra()
    base = replace(base or PlannerConfig(), joint_limits=LIFTED_JOINT_LIMITS)
    joins = joins_of(base)
    total = len(CYCLES) * len(max_accel_jumps) * sum(
        len(_profiles_for(join, profiles)) for join in joins)
    rows = []
    for case, pick, place, policy in CYCLES:
        paper_path = plan_path(pick, place, base.pick_clearance, base.place_clearance, policy,
                               join='paper')
        bound = topp_bound(paper_path, base.limits, join_cap=False)
        for join in joins:
            for jump in max_accel_jumps:
                limits = replace(base.limits, max_accel_jump=jump)
                config = with_join(replace(base, arc=policy, limits=limits), join)
                capped = topp_bound(paper_path, limits) if join == 'paper' else None
                for profile in _profiles_for(join, profiles):
                    leg = plan_transfer(pick, place, replace(config, profile=profile))
                    metrics = leg.motion.metrics()
                    row = {'case': case, 'profile': profile, 'join': join,
                           'max_accel_jump': jump, 'duration_s': leg.motion.duration,
                           'topp_ra_bound_s': bound,
                           'ratio_to_bound': leg.motion.duration / bound,
                           'peak_speed': metrics['peak_speed'],
                           'peak_accel': metrics['peak_accel'],
                           'peak_jerk': metrics['peak_jerk']}
                    if capped is not None:
                        row['topp_ra_bound_join_capped_s'] = capped
                    rows.append(row)
                    if progress is not None:
                        progress(len(rows), total)
    return rows


def _profiles_for(join, profiles):
    """Return the profiles that apply to ``join`` (the paper's node rule needs its path)."""
    return tuple(profile for profile in profiles if join == 'paper' or profile != 'curvature')


def picks_per_minute(base=None):
    """
    Return the picks per minute on the 25-305-25 mm cycle with two 35 ms dwells (planned).

    One period is a whole request from the place: approach leg to the pick, dwell, transfer
    leg to the place, dwell; the robot repeats it. The cycle time is the last
    ``time_from_start`` of the published trajectory, which JTC executes in that time.

    Parameters
    ----------
    base : PlannerConfig, optional
        The node's defaults when omitted.

    Returns
    -------
    dict
        ``cycle``, ``dwell_s``, ``rows`` (one per limit set and join: ``limits``, ``join``,
        ``max_speed``, ``max_accel``, ``max_jerk``, ``joint_limits``, ``cycle_s``,
        ``picks_per_min``) and ``reference`` (ABB's quoted IRB 360 figure).

    """
    base = base or PlannerConfig()
    case, pick, place, policy = CYCLES[1]
    settings = (('default', base.limits, base.joint_limits, 'default'),
                ('fast', replace(FAST_LIMITS, max_accel_jump=base.limits.max_accel_jump),
                 LIFTED_JOINT_LIMITS, 'lifted'))
    rows = []
    for name, limits, joint_limits, joint_text in settings:
        for join in joins_of(base):
            config = with_join(replace(base, arc=policy, limits=limits,
                                       joint_limits=joint_limits), join)
            plan = plan_cycle(place, pick, place, config, pick_dwell=PICK_PLACE_DWELL,
                              place_dwell=PICK_PLACE_DWELL)
            cycle_s = float(plan.joint_trajectory.time_from_start[-1])
            rows.append({'limits': name, 'join': join, 'max_speed': limits.max_speed,
                         'max_accel': limits.max_accel, 'max_jerk': limits.max_jerk,
                         'joint_limits': joint_text, 'cycle_s': cycle_s,
                         'picks_per_min': 60.0 / cycle_s})
    return {'cycle': case, 'dwell_s': [PICK_PLACE_DWELL, PICK_PLACE_DWELL], 'rows': rows,
            'reference': dict(ABB_IRB360)}
