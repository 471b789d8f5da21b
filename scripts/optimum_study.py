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
The jerk-limited time optimum on the planned path, by direct transcription (issue 14, item 4).

How far is the time-optimal scan (``time_motion``) from the true optimum on the same path?
This study computes that optimum on the bench's two cycles and compares it with the scan.
It needs SciPy (``pip install scipy``: HiGHS, through ``scipy.optimize.linprog``), which
is not a dependency of the package, and TOPP-RA for the bound (the ``bench`` extra).

The problem. Along the path parametrised by arc length s, b(s) = s'**2 on a grid of the
bend (T1 to T2), C1 and piecewise quadratic: per node b and d = b' = 2 s'', per interval
c = b'' = 2 s''' / s' (exact continuity b, d between intervals: linear equalities). The
path is planar (checked: the vertical plane through pick and place), so with the signed
curvature kappa and its rate kappa' = dkappa/ds the acceleration is (s'', kappa s'**2)
(tangential, normal) and the jerk (s''' - kappa**2 s'**3, 3 kappa s' s'' + kappa' s'**3);
binormal components vanish. Constraints: s' <= max_speed, the acceleration norm at every
node, the jerk norm at both ends of every interval, and with ``join`` paper the step
kappa_T s'**2 <= max_accel_jump at T1 and T2 (the paper join's acceleration step). The
vertical lift and descent (kappa = 0) are timed in closed form by Ruckig, which is time-optimal
on a line, from rest to the arc's entry state (s', s'') and from its exit state to rest: the
objective is T = T_lift + integral of ds / sqrt(b) over the bend + T_descent.

The solver. Sequential linear programming with an exact l1 penalty and a trust region
(HiGHS per step): the speed and acceleration rows are linear in (b, d); the jerk rows are
linearised at the current point; each norm <= limit is a set of facets (8 fixed directions
and the current direction of the vector, which makes a converged point feasible at the
grid's points exactly). It starts from the scan's own profile (b, s'' sampled along s).
The grid is finest at both ends of the bend (``FINE_STEP``, growing to ``COARSE_STEP``).

The check. The optimum is then re-checked independently of the grid and of the jerk formula:
the bend's time t(s) by Gauss-Legendre quadrature of ds / sqrt(b) on every interval, the
TCP positions from the path at ``CHECK_SAMPLES`` points per interval, velocity, acceleration
and jerk as finite differences in time of the positions, velocities and accelerations
(vectors, so the 3 kappa s' s'' term is checked, not assumed), and Ruckig's lines sampled
densely. The reported ratio uses the re-integrated time.

Studies (planned figures, ratios to TOPP-RA's bound on the paper's path without jerk limit
or join cap, as in ``ellipath bench``):

- ``calibrate``: the paper join (25 m/s² step) on both cycles: scan and optimum.
- ``g2``: the G2 join (default ``join_tolerance`` 0.5 mm): scan and optimum, time per
  region (lift, T1 transition, arc, T2 transition, descent) and b(s) side by side near T1.
- ``tolerance``: the G2 optimum and the scan at other join tolerances and jerk limits
  (``VARIANTS``).

Each optimum is an upper bound of the true one (a feasible motion; SLP finds a local optimum
and stops after ``MAX_STEPS`` steps or when the time stalls) and takes a few CPU minutes.

Limits are the bench's (4 m/s, 50 m/s², 5000 m/s³) scaled by the planner's own margins
(``_SPEED_MARGIN``, ``_ACCEL_MARGIN``, ``_JERK_MARGIN``), which the scan keeps too; ``--full``
uses the limits themselves.

    PYTHONPATH=. python3 scripts/optimum_study.py [calibrate g2 tolerance] [--full]
"""

from dataclasses import dataclass, replace
import math
import sys

from ellipath_ros.bench.cycle import CYCLES, topp_bound
from ellipath_ros.core.geometry import DEFAULT_JOIN_TOLERANCE, plan_path
from ellipath_ros.core.limits import _ACCEL_MARGIN, _JERK_MARGIN, _SPEED_MARGIN, CartesianLimits
from ellipath_ros.core.ruckig_lines import _ruckig_rows
from ellipath_ros.core.timing import time_motion
import numpy as np
from scipy import sparse
from scipy.optimize import linprog

LIMITS = replace(CartesianLimits(), max_accel_jump=25.0)
CLEARANCE = 0.025
# Grid of the bend [m]: FINE_STEP at both ends, growing by GROWTH per interval up to
# COARSE_STEP.
FINE_STEP = 5e-5
COARSE_STEP = 1e-3
GROWTH = 1.04
# Facets of each norm constraint (fixed directions; the current direction is added).
FACETS = 8
# Tangents of 1 / sqrt(b) per node, at b (1 + trust * share): the LP sees the time's curvature.
CUT_POINTS = (-1.0, -0.5, 0.0, 0.5, 1.0)
# Exact penalty weight [s per unit of relative violation], trust region (relative), stops.
PENALTY = 1.0
TRUST_START = 0.05
TRUST_MIN = 1e-7
MAX_STEPS = 400
# Stop when the merit fell by less than STALL (relative) over the last STALL_STEPS steps.
STALL = 1e-5
STALL_STEPS = 50
# Relative violation accepted as feasible at the grid's points, and the check's density.
FEASIBLE = 1e-6
CHECK_SAMPLES = 32
# Gauss-Legendre nodes for the time integral of each interval.
GAUSS_NODES, GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(16)
# Regions reported: millimetres past T1 whose b(s) is printed side by side.
PROFILE_MM = (0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 15.0, 20.0, 30.0)
# (join_tolerance [m], max_jerk [m/s³]) of the tolerance study.
VARIANTS = ((2e-3, 5000.0), (4e-3, 5000.0), (8e-3, 5000.0), (5e-4, 10000.0), (5e-4, 20000.0))


def planner_limits(limits):
    """Return ``limits`` scaled by the planner's own margins (speed, acceleration, jerk)."""
    return replace(limits, max_speed=limits.max_speed * _SPEED_MARGIN,
                   max_accel=limits.max_accel * _ACCEL_MARGIN,
                   max_jerk=limits.max_jerk * _JERK_MARGIN)


def cycle_path(case, join, tolerance=DEFAULT_JOIN_TOLERANCE):
    """Return the path of a bench cycle with ``join``."""
    _, pick, place, policy = case
    return plan_path(pick, place, CLEARANCE, CLEARANCE, policy, join, tolerance)


def line_rows(start, target, limits):
    """
    Return Ruckig's time-optimal pieces between two 1-DoF states (s, s', s''), or None.

    Each row is (duration, s, s', s'', jerk) of a constant-jerk piece; None when Ruckig
    finds nothing or the motion runs backwards (then it is not a motion along the path).
    """
    return _ruckig_rows(start, target, limits.max_speed, limits.max_accel, limits.max_jerk)


def line_time(start, target, limits):
    """Return the duration of :func:`line_rows` (math.inf when there is none)."""
    rows = line_rows(start, target, limits)
    return math.inf if rows is None else float(sum(row[0] for row in rows))


def line_peaks(rows):
    """Return the largest speed, |s''| and |jerk| of constant-jerk pieces (exact per piece)."""
    speed = accel = jerk = 0.0
    for duration, _, v, a, j in rows:
        ends = [v, v + a * duration + 0.5 * j * duration ** 2]
        if j != 0.0 and 0.0 < -a / j < duration:
            ends.append(v - 0.5 * a * a / j)
        speed = max(speed, *(abs(value) for value in ends))
        accel = max(accel, abs(a), abs(a + j * duration))
        jerk = max(jerk, abs(j))
    return speed, accel, jerk


@dataclass
class Bend:
    """The bend's grid: nodes s [m], steps h, signed curvature and its rate at the nodes."""

    s: np.ndarray
    h: np.ndarray
    kappa: np.ndarray
    rate: np.ndarray


def bend_grid(path, fine=FINE_STEP, coarse=COARSE_STEP):
    """Return the bend's :class:`Bend` (arc length from T1), finest at both ends."""
    length = path.segment_lengths[1]
    steps = [fine]
    while sum(steps) < 0.5 * length:
        steps.append(min(steps[-1] * GROWTH, coarse))
    half = np.concatenate(([0.0], np.cumsum(steps)))
    half = half[half < 0.5 * length]
    s = np.unique(np.concatenate((half, [0.5 * length], length - half)))
    kappa, rate = signed_curvature(path, s)
    return Bend(s, np.diff(s), kappa, rate)


def signed_curvature(path, s_bend):
    """
    Return the bend's signed curvature and its rate at bend lengths ``s_bend`` (from T1).

    From the bend's own closed form (on its side of T1 and T2: the paper join's step is
    there). Checks that the path is planar and that, in the path's plane (u, z), the curvature
    vector p'' is kappa n with n the tangent turned a quarter (away from the ends).
    """
    bend = path.bend
    kappa, rate = bend.curvature_and_rate(bend.t_from_s(np.asarray(s_bend, dtype=float)))
    samples = path.at_lengths(path.segment_ends[1] + s_bend)
    normal_of_plane = np.cross(path.direction, [0.0, 0.0, 1.0])
    out_of_plane = max(float(np.abs((samples.position - path.pick) @ normal_of_plane).max()),
                       float(np.abs(samples.curvature_rate @ normal_of_plane).max()))
    if out_of_plane > 1e-9:
        raise RuntimeError(f'path not planar: {out_of_plane:.3g} out of its plane')
    inside = slice(1, -1)
    vector = np.linalg.norm(samples.curvature[inside], axis=1)
    if np.abs(vector - np.abs(kappa[inside])).max() > 1e-6 * max(np.abs(kappa).max(), 1.0):
        raise RuntimeError("the bend's curvature differs from the path's")
    return kappa, rate


class Transcription:
    """
    The jerk-limited time-optimal problem on one path (see the module docstring).

    Variables x = (b at nodes, d = b' at nodes, c = b'' per interval).
    """

    def __init__(self, path, limits, bend=None):
        self.path = path
        self.limits = limits
        self.bend = bend or bend_grid(path)
        self.nodes = self.bend.s.size
        self.intervals = self.nodes - 1
        self.step_cap = path.join == 'paper'
        n, m = self.nodes, self.intervals
        h = self.bend.h
        rows = np.arange(m)
        # b[k+1] - b[k] - d[k] h - c[k] h²/2 = 0 and d[k+1] - d[k] - c[k] h = 0.
        continuity_b = sparse.coo_matrix(
            (np.concatenate((np.ones(m), -np.ones(m), -h, -0.5 * h * h)),
             (np.tile(rows, 4), np.concatenate((rows + 1, rows, n + rows, 2 * n + rows)))),
            shape=(m, 2 * n + m))
        continuity_d = sparse.coo_matrix(
            (np.concatenate((np.ones(m), -np.ones(m), -h)),
             (np.tile(rows, 3), np.concatenate((n + rows + 1, n + rows, 2 * n + rows)))),
            shape=(m, 2 * n + m))
        self.equalities = sparse.vstack((continuity_b, continuity_d)).tocsr()
        angles = 2.0 * math.pi * np.arange(FACETS) / FACETS
        self.directions = np.stack((np.cos(angles), np.sin(angles)), axis=1)
        # Trapezoid weights of the nodes in the integral of ds / sqrt(b).
        self.weights = np.concatenate((0.5 * h, [0.0])) + np.concatenate(([0.0], 0.5 * h))

    def split(self, x):
        """Return (b, d, c) views of ``x``."""
        n = self.nodes
        return x[:n], x[n:2 * n], x[2 * n:]

    def lift_time(self, b0, d0):
        """Return the lift's time to the entry state (s' = sqrt(b0), s'' = d0 / 2)."""
        entry = (self.path.segment_lengths[0], math.sqrt(max(b0, 0.0)), 0.5 * d0)
        return line_time((0.0, 0.0, 0.0), entry, self.limits)

    def descent_time(self, b1, d1):
        """Return the descent's time from the exit state (s' = sqrt(b1), s'' = d1 / 2)."""
        return line_time((0.0, math.sqrt(max(b1, 0.0)), 0.5 * d1),
                         (self.path.segment_lengths[2], 0.0, 0.0), self.limits)

    def bend_time(self, x):
        """Return the bend's time on the grid (trapezoid rule in s) and its gradient by b."""
        b = x[:self.nodes]
        if b.min() <= 0.0:
            return math.inf, None
        grad = np.zeros_like(x)
        grad[:self.nodes] = -0.5 * self.weights * b ** -1.5
        return float(self.weights @ b ** -0.5), grad

    def objective(self, x, gradient=True):
        """Return T(x) and, with ``gradient``, dT/dx (lines by finite differences)."""
        b, d, _ = self.split(x)
        time, grad = self.bend_time(x)
        if grad is None:
            return math.inf, None
        lift = self.lift_time(b[0], d[0])
        descent = self.descent_time(b[-1], d[-1])
        total = time + lift + descent
        if not gradient or not math.isfinite(total):
            return total, grad
        n = self.nodes
        for index, end, function, value in ((0, 0, self.lift_time, lift),
                                            (n - 1, -1, self.descent_time, descent)):
            step_b, step_d = 1e-7 * max(b[end], 1e-3), 1e-6
            forward_b = function(b[end] + step_b, d[end])
            forward_d = function(b[end], d[end] + step_d)
            if not math.isfinite(forward_b):
                forward_b = 2.0 * value - function(b[end] - step_b, d[end])
            if not math.isfinite(forward_d):
                forward_d = 2.0 * value - function(b[end], d[end] - step_d)
            grad[index] += (forward_b - value) / step_b
            grad[n + index] += (forward_d - value) / step_d
        return total, grad

    def vectors(self, x):
        """
        Return the acceleration at the nodes and the jerk at the ends of each interval.

        Each as (tangential, normal), with the jerk's partial derivatives by (b, d, c) at that
        end: accel (2, n); jerk (2, 2m) for ends (left of interval k, then right), and the
        node index of each end.
        """
        b, d, c = self.split(x)
        kappa, rate = self.bend.kappa, self.bend.rate
        accel = np.stack((0.5 * d, kappa * b))
        m = self.intervals
        node = np.concatenate((np.arange(m), np.arange(1, m + 1)))
        cc = np.concatenate((c, c))
        bn, dn, kn, rn = b[node], d[node], kappa[node], rate[node]
        root = np.sqrt(np.maximum(bn, 1e-12))
        jerk = np.stack((0.5 * root * cc - kn * kn * bn * root,
                         1.5 * kn * root * dn + rn * bn * root))
        partial_b = np.stack((0.25 * cc / root - 1.5 * kn * kn * root,
                              0.75 * kn * dn / root + 1.5 * rn * root))
        partial_d = np.stack((np.zeros(2 * m), 1.5 * kn * root))
        partial_c = np.stack((0.5 * root, np.zeros(2 * m)))
        return accel, jerk, node, (partial_b, partial_d, partial_c)

    def violation(self, x):
        """Return the sum of relative violations of every constraint at the grid's points."""
        b, _, _ = self.split(x)
        accel, jerk, _, _ = self.vectors(x)
        limits = self.limits
        parts = [np.maximum(b / limits.max_speed ** 2 - 1.0, 0.0),
                 np.maximum(np.hypot(*accel) / limits.max_accel - 1.0, 0.0),
                 np.maximum(np.hypot(*jerk) / limits.max_jerk - 1.0, 0.0)]
        if self.step_cap:
            ends = np.abs(self.bend.kappa[[0, -1]]) * b[[0, -1]]
            parts.append(np.maximum(ends / limits.max_accel_jump - 1.0, 0.0))
        return float(sum(part.sum() for part in parts))

    def facet_rows(self, vector, limit, partials, columns):
        """
        Return sparse rows of the facets of |vector| <= limit, linearised.

        ``vector`` (2, K) at the current point; ``partials`` a list of (2, K) derivatives by
        the variables in ``columns`` (a list of (K,) column indices). Rows are
        (direction . partials) dx <= limit - direction . vector, divided by ``limit``.
        The current direction is added where the vector exceeds a quarter of the limit.
        Returns (matrix rows, right-hand side, constraint index of each row).
        """
        size = vector.shape[1]
        magnitude = np.hypot(*vector)
        own = vector / np.maximum(magnitude, 1e-300)
        entries = []
        for direction in self.directions:
            entries.append((np.arange(size), np.broadcast_to(direction[:, None], (2, size))))
        near = np.flatnonzero(magnitude > 0.25 * limit)
        entries.append((near, own[:, near]))
        data, row_index, col_index, rhs, owner = [], [], [], [], []
        row = 0
        for which, direction in entries:
            count = which.size
            for partial, column in zip(partials, columns):
                data.append(np.sum(direction * partial[:, which], axis=0) / limit)
                row_index.append(row + np.arange(count))
                col_index.append(column[which])
            rhs.append(1.0 - np.sum(direction * vector[:, which], axis=0) / limit)
            owner.append(which)
            row += count
        return (np.concatenate(data), np.concatenate(row_index), np.concatenate(col_index),
                row, np.concatenate(rhs), np.concatenate(owner))

    def linear_program(self, x, grad, trust):
        """Solve the step's LP; return (step, predicted merit)."""
        n, m = self.nodes, self.intervals
        size = 2 * n + m
        limits = self.limits
        accel, jerk, node, (partial_b, partial_d, partial_c) = self.vectors(x)
        nodes = np.arange(n)
        blocks = []
        # Acceleration: (d/2, kappa b) is linear: partials by b and d.
        blocks.append(self.facet_rows(
            accel, limits.max_accel,
            [np.stack((np.zeros(n), self.bend.kappa)), np.stack((np.full(n, 0.5), np.zeros(n)))],
            [nodes, n + nodes]))
        interval = np.concatenate((np.arange(m), np.arange(m)))
        blocks.append(self.facet_rows(jerk, limits.max_jerk, [partial_b, partial_d, partial_c],
                                      [node, n + node, 2 * n + interval]))
        matrices, rhs, owners, slack_offset = [], [], [], 0
        for data, rows, cols, count, right, owner in blocks:
            matrices.append(sparse.coo_matrix((data, (rows, cols)), shape=(count, size)))
            rhs.append(right)
            owners.append(owner + slack_offset)
            slack_offset += owner.max() + 1
        b = x[:n]
        # Speed: b + db <= vmax² (relative rows), slack per node.
        matrices.append(sparse.coo_matrix((np.full(n, 1.0 / limits.max_speed ** 2),
                                           (nodes, nodes)), shape=(n, size)))
        rhs.append(1.0 - b / limits.max_speed ** 2)
        owners.append(nodes + slack_offset)
        slack_offset += n
        if self.step_cap:
            ends = np.array([0, n - 1])
            scale = np.abs(self.bend.kappa[ends]) / limits.max_accel_jump
            matrices.append(sparse.coo_matrix((scale, ([0, 1], ends)), shape=(2, size)))
            rhs.append(1.0 - scale * b[ends])
            owners.append(np.arange(2) + slack_offset)
            slack_offset += 2
        # Epigraph of the bend's time: tau >= 1 / sqrt(b) by tangents inside the trust region.
        cuts = []
        for share in CUT_POINTS:
            at = b * (1.0 + min(trust, 0.9) * share)
            slope = -0.5 * at ** -1.5
            cuts.append((slope, -at ** -0.5 - slope * (b - at)))
        count = len(cuts) * n
        cut_rows = np.arange(count)
        matrices.append(sparse.coo_matrix(
            (np.concatenate([slope for slope, _ in cuts] + [-np.ones(count)]),
             (np.concatenate((cut_rows, cut_rows)),
              np.concatenate((np.tile(nodes, len(cuts)), size + np.tile(nodes, len(cuts)))))),
            shape=(count, size + n)))
        rhs.append(np.concatenate([right for _, right in cuts]))
        matrices = [matrix if matrix.shape[1] == size + n else sparse.hstack(
            (matrix, sparse.csr_matrix((matrix.shape[0], n)))) for matrix in matrices]
        # The cuts carry no slack: their owner column is a dummy fixed at 0.
        owners.append(np.full(count, slack_offset))
        slack_offset += 1
        rows = sparse.vstack(matrices).tocsr()
        owner = np.concatenate(owners)
        slacks = sparse.coo_matrix((-np.ones(owner.size), (np.arange(owner.size), owner)),
                                   shape=(owner.size, slack_offset))
        upper = sparse.hstack((rows, slacks)).tocsr()
        equal = sparse.hstack((self.equalities, sparse.csr_matrix(
            (self.equalities.shape[0], n + slack_offset)))).tocsr()
        _, d, c = self.split(x)
        radius = np.concatenate((trust * (b + 0.01), trust * (np.abs(d) + 5.0),
                                 trust * (np.abs(c) + 500.0)))
        bounds = np.concatenate((np.stack((-radius, radius), axis=1),
                                 np.tile([0.0, np.inf], (n, 1)),
                                 np.tile([0.0, np.inf], (slack_offset, 1))))
        bounds[-1] = (0.0, 0.0)
        # b stays positive.
        bounds[:n, 0] = np.maximum(bounds[:n, 0], 1e-4 - b)
        # The lines' gradient stays linear; the bend's time is sum(weights * tau).
        lines = grad.copy()
        lines[:n] += 0.5 * self.weights * b ** -1.5
        cost = np.concatenate((lines, self.weights, np.full(slack_offset, PENALTY)))
        result = linprog(cost, A_ub=upper, b_ub=np.concatenate(rhs), A_eq=equal,
                         b_eq=-self.equalities @ x, bounds=bounds, method='highs')
        if result.status != 0:
            return None, None
        # The model's T excludes the lines' values at x: add them back.
        lines_now = self.objective(x, gradient=False)[0] - self.bend_time(x)[0]
        return result.x[:size], float(result.fun) + lines_now

    def merit(self, x):
        """Return (T, penalised merit) at x."""
        time = self.objective(x, gradient=False)[0]
        return time, time + PENALTY * self.violation(x)

    def solve(self, x, log=None):
        """Run the SLP from x; return (x, T, violation, steps)."""
        trust = TRUST_START
        time, merit = self.merit(x)
        steps = 0
        history = []
        while steps < MAX_STEPS and trust > TRUST_MIN:
            steps += 1
            history.append(merit)
            if (len(history) > STALL_STEPS and history[-STALL_STEPS - 1] - merit < STALL * time
                    and self.violation(x) <= FEASIBLE):
                break
            _, grad = self.objective(x)
            step, predicted = self.linear_program(x, grad, trust)
            if step is None:
                trust *= 0.5
                continue
            # The model's merit at the step: T + grad.dx + penalty of the linearised rows.
            decrease = merit - predicted
            trial = x + step
            trial_time, trial_merit = self.merit(trial)
            actual = merit - trial_merit
            if decrease <= 1e-12 * time:
                if self.violation(x) <= FEASIBLE:
                    break
                trust *= 0.5
                continue
            ratio = actual / decrease
            if ratio > 0.1:
                x, time, merit = trial, trial_time, trial_merit
                if ratio > 0.75:
                    trust = min(trust * 2.0, 0.5)
            else:
                trust *= 0.3
            if log is not None and steps % 20 == 0:
                log(f'    step {steps}: T {time:.6f} s, violation {self.violation(x):.2e}, '
                    f'trust {trust:.1e}')
        return x, time, self.violation(x), steps

    def start_from(self, motion):
        """Return x from a timed motion (the scan's): b, s'' along the bend, made consistent."""
        times = np.linspace(0.0, motion.duration, 200001)
        s, v, a, _ = motion.path_state(times)
        s_nodes = self.path.segment_ends[1] + self.bend.s
        d = 2.0 * np.interp(s_nodes, s, a)
        c = np.diff(d) / self.bend.h
        b = np.empty(self.nodes)
        b[0] = float(np.interp(s_nodes[0], s, v)) ** 2
        b[1:] = b[0] + np.cumsum(0.5 * (d[:-1] + d[1:]) * self.bend.h)
        return np.concatenate((b, d, c))


def verify(problem, x):
    """
    Re-check the optimum x off the grid and without the jerk formula; return a dict.

    Times by quadrature, the TCP by the path at ``CHECK_SAMPLES`` points per interval,
    derivatives as finite differences in time of the vectors; the lines from Ruckig's
    trajectories sampled densely.
    """
    path, limits, bend = problem.path, problem.limits, problem.bend
    b, d, c = problem.split(x)
    h = bend.h
    # Time per interval: Gauss-Legendre on b(s) = b + d x + c x²/2.
    local = 0.5 * (GAUSS_NODES + 1.0)[None, :] * h[:, None]
    values = b[:-1, None] + d[:-1, None] * local + 0.5 * c[:, None] * local ** 2
    if values.min() <= 0.0:
        raise RuntimeError('b(s) not positive inside the bend')
    bend_time = float(np.sum(0.5 * h * (GAUSS_WEIGHTS[None, :] / np.sqrt(values)).sum(axis=1)))
    # Dense samples: s, and t(s) by cumulative quadrature on sub-intervals.
    fractions = np.arange(CHECK_SAMPLES) / CHECK_SAMPLES
    s_local = fractions[None, :] * h[:, None]
    s_dense = np.concatenate(((bend.s[:-1, None] + s_local).ravel(), [bend.s[-1]]))
    interval = np.minimum(np.searchsorted(bend.s, s_dense, side='right') - 1,
                          problem.intervals - 1)
    offset = s_dense - bend.s[interval]

    def b_at(which, where):
        return b[which] + d[which] * where + 0.5 * c[which] * where ** 2

    step = np.diff(s_dense)
    start = offset[:-1]
    nodes = 0.5 * (GAUSS_NODES + 1.0)[None, :] * step[:, None] + start[:, None]
    dt = 0.5 * step * (GAUSS_WEIGHTS[None, :] / np.sqrt(
        b_at(interval[:-1, None], nodes))).sum(axis=1)
    t_dense = np.concatenate(([0.0], np.cumsum(dt)))
    samples = path.at_lengths(path.segment_ends[1] + s_dense)
    # The curvature on the bend's side of T1 and T2 (the paper join steps there).
    inside = np.clip(s_dense, 1e-9, bend.s[-1] - 1e-9)
    curvature = path.at_lengths(path.segment_ends[1] + inside).curvature
    speed = np.sqrt(b_at(interval, offset))
    # Finite differences in time (central, non-uniform) of positions, velocities, accels.

    def derivative(values, times):
        forward = np.diff(values, axis=0) / np.diff(times)[:, None]
        middle = 0.5 * (times[1:] + times[:-1])
        return forward, middle

    fd_velocity, t1 = derivative(samples.position, t_dense)
    fd_accel, _ = derivative(fd_velocity, t1)
    accel_exact = (samples.tangent * (0.5 * (d[interval] + c[interval] * offset))[:, None]
                   + curvature * (speed ** 2)[:, None])
    jerk_fd_of_exact, _ = derivative(accel_exact, t_dense)
    # The lines: Ruckig's constant-jerk pieces, peaks exact per piece.
    entry = (path.segment_lengths[0], math.sqrt(b[0]), 0.5 * d[0])
    exit_state = (0.0, math.sqrt(b[-1]), 0.5 * d[-1])
    lines = (line_rows((0.0, 0.0, 0.0), entry, limits),
             line_rows(exit_state, (path.segment_lengths[2], 0.0, 0.0), limits))
    durations = [float(sum(row[0] for row in rows)) for rows in lines]
    peaks = np.array([line_peaks(rows) for rows in lines])
    total = durations[0] + bend_time + durations[1]
    step_ends = (float(abs(bend.kappa[0]) * b[0]), float(abs(bend.kappa[-1]) * b[-1]))
    return {
        'duration': total,
        'segments': (durations[0], bend_time, durations[1]),
        'peak_speed': max(float(speed.max()), peaks[:, 0].max()),
        'fd_speed': float(np.linalg.norm(fd_velocity, axis=1).max()),
        'peak_accel': max(float(np.linalg.norm(accel_exact, axis=1).max()), peaks[:, 1].max()),
        'fd_accel': float(np.linalg.norm(fd_accel, axis=1).max()),
        'fd_jerk': float(np.linalg.norm(jerk_fd_of_exact, axis=1).max()),
        'line_jerk': float(peaks[:, 2].max()),
        'accel_steps': step_ends if problem.step_cap else (0.0, 0.0),
        't_dense': t_dense, 's_dense': s_dense, 'speed': speed,
    }


BOUNDS = {}


def bound_of(case):
    """Return TOPP-RA's bound on a cycle's paper path (no jerk limit, no join cap)."""
    if case[0] not in BOUNDS:
        BOUNDS[case[0]] = topp_bound(cycle_path(case, 'paper'), LIMITS, join_cap=False)
    return BOUNDS[case[0]]


def optimum(path, limits, plan_limits, log=print):
    """Return (scan motion, problem, x, verification) for ``path``."""
    motion = time_motion(path, plan_limits)
    problem = Transcription(path, limits)
    x = problem.start_from(motion)
    x, time, violation, steps = problem.solve(x, log=log)
    check = verify(problem, x)
    log(f'    SLP: {steps} steps, T {time:.6f} s on the grid, violation {violation:.1e}; '
        f'{problem.nodes} nodes')
    return motion, problem, x, check


def report_check(case, motion, check, limits, log=print):
    """Print the scan's and the optimum's ratios and the optimum's verified peaks."""
    bound = bound_of(case)
    log(f'    scan {motion.duration / bound:.4f} ({1e3 * motion.duration:.2f} ms)   '
        f"optimum {check['duration'] / bound:.4f} ({1e3 * check['duration']:.2f} ms; "
        f"lift / bend / descent {', '.join(f'{1e3 * value:.2f}' for value in check['segments'])}"
        f' ms; scan {1e3 * motion.segment_durations[0]:.2f} / '
        f'{1e3 * motion.segment_durations[1]:.2f} / {1e3 * motion.segment_durations[2]:.2f})')
    log(f"    optimum checked (planned): speed {check['peak_speed']:.4f} (FD "
        f"{check['fd_speed']:.4f}) of {limits.max_speed:.4g} m/s; accel "
        f"{check['peak_accel']:.3f} (FD {check['fd_accel']:.3f}) of {limits.max_accel:.4g}; "
        f"jerk (FD of the accel vector) {check['fd_jerk']:.0f}, lines {check['line_jerk']:.0f} of "
        f'{limits.max_jerk:.5g} m/s³; steps at T1/T2 '
        f"{check['accel_steps'][0]:.2f} / {check['accel_steps'][1]:.2f} m/s²")


def study_limits(full):
    """Return (limits of the optimum, limits given to the scan)."""
    return (LIMITS if full else planner_limits(LIMITS)), LIMITS


def calibrate(full=False, log=print):
    """Paper join: scan against the optimum on both cycles."""
    limits, plan_limits = study_limits(full)
    log('## calibrate: paper join (25 m/s² step), planned ratios to the bound')
    for case in CYCLES:
        log(f'  {case[0]}')
        motion, _, _, check = optimum(cycle_path(case, 'paper'), limits, plan_limits, log)
        report_check(case, motion, check, limits, log)


def regions(path):
    """Return the bend's region bounds (T1, end of transition 1, start of transition 2, T2)."""
    bend = path.bend
    inner = bend.s_from_t(np.array([math.pi - bend.span_1, bend.span_2]))
    return np.array([0.0, inner[0], inner[1], path.segment_lengths[1]])


def region_times(path, times, s_bend):
    """Return the time spent in each bend region, from samples t(s) of the bend."""
    bounds = regions(path)
    at = np.interp(bounds, s_bend, times)
    return np.diff(at)


def scan_states(motion, s_bend):
    """Return the scan's (time from T1, speed) at bend lengths ``s_bend``."""
    times = np.linspace(0.0, motion.duration, 400001)
    s, v, _, _ = motion.path_state(times)
    absolute = motion.path.segment_ends[1] + s_bend
    return np.interp(absolute, s, times) - motion.segment_durations[0], np.interp(absolute, s, v)


def g2(full=False, log=print):
    """G2 join: scan against the optimum, per region, and b(s) near T1."""
    limits, plan_limits = study_limits(full)
    log('## g2: join g2 (join_tolerance 0.5 mm), planned ratios to the bound')
    for case in CYCLES:
        log(f'  {case[0]}')
        path = cycle_path(case, 'g2')
        motion, _, _, check = optimum(path, limits, plan_limits, log)
        report_check(case, motion, check, limits, log)
        scan_t, scan_v = scan_states(motion, check['s_dense'])
        scan_regions = region_times(path, scan_t, check['s_dense'])
        best_regions = region_times(path, check['t_dense'], check['s_dense'])
        bounds = regions(path)
        log(f'    regions [ms] scan / optimum: lift {1e3 * motion.segment_durations[0]:.2f} / '
            f"{1e3 * check['segments'][0]:.2f}; T1 transition ({1e3 * bounds[1]:.1f} mm) "
            f'{1e3 * scan_regions[0]:.2f} / {1e3 * best_regions[0]:.2f}; arc '
            f'{1e3 * scan_regions[1]:.2f} / {1e3 * best_regions[1]:.2f}; T2 transition '
            f'({1e3 * (bounds[3] - bounds[2]):.1f} mm) {1e3 * scan_regions[2]:.2f} / '
            f'{1e3 * best_regions[2]:.2f}; descent {1e3 * motion.segment_durations[2]:.2f} / '
            f"{1e3 * check['segments'][2]:.2f}")
        marks = np.array(PROFILE_MM) * 1e-3
        scan_at = np.interp(marks, check['s_dense'], scan_v)
        best_at = np.interp(marks, check['s_dense'], check['speed'])
        kappa = np.interp(marks, problem_bend_s(path), problem_bend_kappa(path))
        log("    speed s' [m/s] past T1 (mm: scan / optimum, kappa 1/m): " + ', '.join(
            f'{mm:g}: {scan:.3f} / {best:.3f} ({k:.0f})'
            for mm, scan, best, k in zip(PROFILE_MM, scan_at, best_at, kappa)))


def problem_bend_s(path):
    """Return a dense grid of the bend's first 40 mm."""
    return np.linspace(0.0, min(0.04, path.segment_lengths[1]), 4001)


def problem_bend_kappa(path):
    """Return the signed curvature on :func:`problem_bend_s`."""
    return signed_curvature(path, problem_bend_s(path))[0]


def tolerance(full=False, log=print):
    """G2 optimum and scan at other join tolerances and jerk limits."""
    limits, plan_limits = study_limits(full)
    log('## tolerance: join g2, optimum (scan) ratio per cycle at other join_tolerance and '
        'max_jerk (the bound has no jerk limit: it stays the same)')
    for value, jerk in VARIANTS:
        row = []
        for case in CYCLES:
            path = cycle_path(case, 'g2', value)
            motion, _, _, check = optimum(
                path, replace(limits, max_jerk=limits.max_jerk * jerk / LIMITS.max_jerk),
                replace(plan_limits, max_jerk=jerk), log=lambda _: None)
            bound = bound_of(case)
            row.append(f"{check['duration'] / bound:.4f} ({motion.duration / bound:.4f})")
        log(f'  join_tolerance {1e3 * value:.1f} mm, max_jerk {jerk:.0f} m/s³: '
            + ' | '.join(row))


STUDIES = {'calibrate': calibrate, 'g2': g2, 'tolerance': tolerance}


def main(argv):
    full = '--full' in argv
    names = [name for name in argv if name != '--full'] or list(STUDIES)
    print('cycles: ' + ' | '.join(case[0] for case in CYCLES)
          + ('; limits as given' if full else "; limits with the planner's margins"))
    for name in names:
        STUDIES[name](full)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
