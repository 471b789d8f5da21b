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
The paper's curvature profile (section 2.3): the node rule on the arc, Ruckig on the lines.

Nodes theta_i with Delta theta_i = r rho(theta_i), one fixed time step
Delta t apart (:func:`curvature_nodes`). Between the nodes we use the
continuous limit of that rule, d theta / dt = -K rho(theta) with
K = r / Delta t [rad/(m s)]: it passes through the same kind of node
spacing (the nodes are its explicit Euler steps), and it has closed-form
speed, acceleration and jerk. With theta(t) fixed, the arc motion scales
uniformly with K (v ~ K, a ~ K**2, j ~ K**3, the acceleration step at
T1/T2 ~ K**2), so Delta t is chosen as small as the Cartesian limits, the
optional speed cap and ``max_accel_jump`` allow. The vertical segments are
timed with Ruckig from rest to the arc's entry state (position, speed,
tangential acceleration) and from its exit state to rest; a clearance too
short for that entry state slows the arc down (larger Delta t). With a
clearance of 0 the arc itself must start (end) at rest, which the rule
never does: a Ruckig ramp along the arc from rest to the state at the
first node that admits one (from the last such node to rest) replaces
the rule there. The same ramps (and lines from rest to rest) are used
when ``max_accel_jump`` would otherwise be what limits Delta t (with 0,
always): the rule's speed at T1/T2 is tiny, so stopping there costs
next to nothing, while a step-limited Delta t would slow the whole arc.
"""

from dataclasses import dataclass, field
import math

import numpy as np

from .errors import InvalidInputError, LimitError, require_range
from .geometry import EllipticArc, radius_of_curvature_derivatives
from .limits import _ACCEL_MARGIN, _cap_values, _JERK_MARGIN, _SPEED_MARGIN
from .motion import _pieces_law, _Sequence, TimedMotion
from .ruckig_lines import _constant_limits, _line_rows, _ruckig_rows, _straight_motion

# Where a ramp may end, in shares of the arc's parameter range, after the nodes.
_RAMP_FRACTIONS = np.array([1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.2])
# The paper's node list is refused beyond this many nodes (r far too small).
_MAX_NODES = 20000
# Time table of the curvature law: Gauss-Legendre panels over the arc.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_ODE_PANELS = 256
_BASELINE_SAMPLES = 4001


@dataclass(frozen=True, eq=False)
class _CurvatureArcLaw:
    """
    The paper's law on the arc: d theta/dt = -K rho(theta), from theta_start down to theta_end.

    With sigma = |dP/dtheta| = sqrt(a**2 sin**2 + b**2 cos**2) and rho = sigma**3 / (a b):
    s' = K sigma**4 / (a b), s'' = -4 K**2 sigma**6 sigma_1 / (a b)**2,
    s''' = 4 K**3 sigma**8 (6 sigma_1**2 + sigma sigma_2) / (a b)**3 (sigma_i: derivatives
    by theta), and t(theta) = (a b / K) * integral of sigma**-3 from theta to theta_start.
    """

    arc: EllipticArc
    rate: float  # K [rad/(m s)]
    s_offset: float  # path length at theta_T1 [m]
    theta_start: float
    theta_end: float
    _edges: np.ndarray = field(init=False, repr=False)
    _times: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        edges = np.linspace(self.theta_start, self.theta_end, _ODE_PANELS + 1)
        object.__setattr__(self, '_edges', edges)
        object.__setattr__(self, '_times', np.concatenate(
            ([0.0], np.cumsum(self._elapsed(edges[:-1], edges[1:])))))

    @property
    def duration(self):
        return float(self._times[-1])

    def _elapsed(self, theta_from, theta_to):
        """Return the time from theta_from down to theta_to (elementwise), >= 0."""
        half = 0.5 * (theta_to - theta_from)
        nodes = (0.5 * (theta_to + theta_from))[..., None] + half[..., None] * _GL_NODES
        ab = self.arc.a * self.arc.b
        return np.abs(half) * ab / self.rate * (self.arc.sigma(nodes)[0] ** -3 @ _GL_WEIGHTS)

    def theta(self, t):
        """Return theta at times ``t`` (N,) from the start of this law (Newton on the table)."""
        t = np.clip(t, 0.0, self.duration)
        panel = np.clip(np.searchsorted(self._times, t, side='right') - 1, 0, _ODE_PANELS - 1)
        theta_0, theta_1 = self._edges[panel], self._edges[panel + 1]
        t_0, t_1 = self._times[panel], self._times[panel + 1]
        theta = theta_0 + (theta_1 - theta_0) * (t - t_0) / np.maximum(t_1 - t_0, 1e-300)
        ab = self.arc.a * self.arc.b
        for _ in range(4):
            residual = t_0 + self._elapsed(theta_0, theta) - t
            # dt/dtheta = -a b / (K sigma**3)
            theta = np.clip(theta + residual * self.rate * self.arc.sigma(theta)[0] ** 3 / ab,
                            theta_1, theta_0)
        return theta

    def state(self, t):
        theta = self.theta(t)
        rate, ab = self.rate, self.arc.a * self.arc.b
        sigma, sigma_1, sigma_2 = self.arc.sigma(theta)
        s = self.s_offset + self.arc.s_from_t(self.arc.t_from_theta(theta))
        speed = rate * sigma ** 4 / ab
        accel = -4.0 * rate ** 2 * sigma ** 6 * sigma_1 / ab ** 2
        jerk = 4.0 * rate ** 3 * sigma ** 8 * (6.0 * sigma_1 ** 2 + sigma * sigma_2) / ab ** 3
        return s, speed, accel, jerk


def curvature_nodes(arc, r=0.77):
    """
    Return the paper's node list (section 2.3, Steps 3-8): theta_i [rad], shape (n,).

    theta_1 = theta_T1; theta_{i+1} = theta_i - r rho(theta_i) while
    theta_i > theta_T2; the last node, which Step 7 lets overshoot T2, is
    clamped to theta_T2 (erratum 6). r is in rad/m; the paper's example gives
    80 nodes with r = 0.77.

    Raises
    ------
    InvalidInputError
        r <= 0, or so small that the list would exceed ``_MAX_NODES``.

    """
    r = require_range('r', r, 0.0, math.inf, low_open=True, unit='rad/m')
    # Node count ~ integral of dtheta / (r rho): refuse huge lists before building them.
    law = _CurvatureArcLaw(arc, 1.0, 0.0, arc.theta_T1, arc.theta_T2)
    estimate = law.duration / r
    if estimate > _MAX_NODES:
        raise InvalidInputError(
            f'r: expected a value giving at most {_MAX_NODES} nodes (r >= '
            f'{law.duration / _MAX_NODES:.3g} rad/m for this arc), got {r!r} rad/m')
    theta = arc.theta_T1
    nodes = [theta]
    while theta > arc.theta_T2:
        theta -= r * float(arc.radius_of_curvature(theta))
        nodes.append(theta)
    nodes[-1] = arc.theta_T2
    return np.array(nodes)


def _arc_cartesian_peaks(arc, theta):
    """Return |v|, |a|, |j| of the rule with K = 1 at ``theta`` (paper frame), each (N,)."""
    rho, rho_1, rho_2 = radius_of_curvature_derivatives(arc.a, arc.b, theta)
    # theta' = -rho, theta'' = rho rho_1, theta''' = -rho (rho_1**2 + rho rho_2) for K = 1.
    w1, w2, w3 = -rho, rho * rho_1, -rho * (rho_1 ** 2 + rho * rho_2)
    p = arc.point(arc.t_from_theta(theta))
    d1 = arc.derivative(arc.t_from_theta(theta))
    # d2P/dtheta2 = -P and d3P/dtheta3 = -dP/dtheta (ellipse about its centre).
    velocity = d1 * w1[:, None]
    accel = -p * (w1 ** 2)[:, None] + d1 * w2[:, None]
    jerk = -d1 * (w1 ** 3)[:, None] - 3.0 * p * (w1 * w2)[:, None] + d1 * w3[:, None]
    return (np.linalg.norm(velocity, axis=1), np.linalg.norm(accel, axis=1),
            np.linalg.norm(jerk, axis=1))


def _curvature_state(arc, rate, theta):
    """Return (s from T1 [m], s', s'') of the rule at a scalar ``theta``."""
    ab = arc.a * arc.b
    sigma, sigma_1, _ = (float(value) for value in arc.sigma(theta))
    return (float(arc.s_from_t(arc.t_from_theta(theta))), rate * sigma ** 4 / ab,
            -4.0 * rate ** 2 * sigma ** 6 * sigma_1 / ab ** 2)


def _curvature_motion(path, limits, r, speed_cap):
    """Build the paper's profile (module docstring): the rule on the arc, Ruckig elsewhere."""
    if path.arc is None:
        return _straight_motion(path, limits, speed_cap, 'curvature')
    arc = path.arc
    nodes = curvature_nodes(arc, r)
    # The tightest point (theta = 0 mod pi) is sampled exactly.
    theta = np.linspace(arc.theta_T1, arc.theta_T2, _BASELINE_SAMPLES)
    theta = np.sort(np.append(theta, math.pi * math.ceil(arc.theta_T2 / math.pi)))[::-1]
    speed, accel, jerk = _arc_cartesian_peaks(arc, theta)
    rate = min(limits.max_speed * _SPEED_MARGIN / speed.max(),
               math.sqrt(limits.max_accel * _ACCEL_MARGIN / accel.max()),
               (limits.max_jerk * _JERK_MARGIN / jerk.max()) ** (1.0 / 3.0))
    if speed_cap is not None:
        s = path.segment_lengths[0] + arc.s_from_t(arc.t_from_theta(theta))
        rate = min(rate, _SPEED_MARGIN * float(np.min(_cap_values(speed_cap, s) / speed)))
    # Step at T1/T2: s'**2 / rho_T <= max_accel_jump, s' = K u_T (same u at both ends). When
    # that would slow the whole arc down, the arc starts and ends at rest (ramps) instead.
    ramps = math.sqrt(limits.max_accel_jump * arc.end_radius) / speed[0] < rate
    # The entry and exit states scale with K: shrink it until the lines (or ramps) fit.
    groups = None
    for _ in range(40):
        groups = _curvature_groups(path, limits, speed_cap, nodes, rate, ramps)
        if groups is not None:
            break
        rate *= 0.8
    if groups is None:
        raise LimitError('curvature profile: expected an arc speed the clearances can reach '
                         f'within the limits, got none down to K = {rate:.3g} rad/(m s)')
    laws = tuple(law for group in groups for law in group)
    segments = np.array([sum(law.duration for law in group) for group in groups])
    v_t1 = v_t2 = 0.0
    if not ramps:
        # Where a ramp starts (ends) the arc, s' = 0 there exactly.
        first_arc, last_arc = groups[1][0], groups[1][-1]
        if path.segment_lengths[0] > 0.0:
            v_t1 = float(first_arc.state(np.zeros(1))[1][0])
        if path.segment_lengths[2] > 0.0:
            v_t2 = float(last_arc.state(np.array([last_arc.duration]))[1][0])
    law = _Sequence(laws)
    return TimedMotion(path, 'curvature', law.duration, segments,
                       v_t1 ** 2 / arc.end_radius, v_t2 ** 2 / arc.end_radius,
                       int(nodes.size), law, node_period=r / rate)


def _curvature_groups(path, limits, speed_cap, nodes, rate, ramps):
    """
    Return (lift laws, arc laws, descent laws) for the rule at rate K, or None if none fit.

    The arc starts (ends) at rest with a ramp when its clearance is 0 or
    ``ramps`` is set; the line then runs from rest to rest.
    """
    arc = path.arc
    c1, arc_length, c2 = path.segment_lengths
    count = nodes.size
    lift, descent, arc_laws = [], [], []
    theta_start, theta_end = arc.theta_T1, arc.theta_T2
    ramp_in = ramp_out = None
    if c1 > 0.0:
        entry = (0.0, 0.0, 0.0) if ramps else _curvature_state(arc, rate, theta_start)
        rows = _line_rows((0.0, 0.0, 0.0), (c1, entry[1], entry[2]), limits, speed_cap,
                          0.0, c1)
        if rows is None:
            return None
        lift.append(_pieces_law(rows))
    if c1 <= 0.0 or ramps:
        ramp_in = _curvature_ramp(path, limits, rate, np.sort(np.concatenate((
            nodes[_ramp_nodes(count)], arc.theta_T1 - math.pi * _RAMP_FRACTIONS)))[::-1], True)
        if ramp_in is None:
            return None
        theta_start = ramp_in[0]
        arc_laws.append(_pieces_law(ramp_in[1], c1))
    if c2 <= 0.0 or ramps:
        ramp_out = _curvature_ramp(path, limits, rate, np.sort(np.concatenate((
            nodes[count - 1 - _ramp_nodes(count)], arc.theta_T2 + math.pi * _RAMP_FRACTIONS))),
            False)
        if ramp_out is None or ramp_out[0] >= theta_start:
            return None
        theta_end = ramp_out[0]
    arc_laws.append(_CurvatureArcLaw(arc, rate, c1, theta_start, theta_end))
    if ramp_out is not None:
        arc_laws.append(_pieces_law(ramp_out[1], c1))
    if c2 > 0.0:
        exit_state = (0.0, 0.0, 0.0) if ramps else _curvature_state(arc, rate, theta_end)
        rows = _line_rows((c1 + arc_length, exit_state[1], exit_state[2]),
                          (path.length, 0.0, 0.0), limits, speed_cap, c1 + arc_length,
                          path.length)
        if rows is None:
            return None
        descent.append(_pieces_law(rows))
    return tuple(lift), tuple(arc_laws), tuple(descent)


def _ramp_nodes(count):
    """Return the indices of the nodes a ramp may end at: 1, 2, 3, 5, ... up to a quarter."""
    return np.unique(np.geomspace(1, max(count // 4, 1), 12).astype(int))


def _curvature_ramp(path, limits, rate, candidates, starting):
    """
    Return (theta, Ruckig rows along the arc) from rest to the rule's state at theta (or back).

    For a clearance of 0 the arc starts (ends) at rest; of the candidates
    (nodes near the end and points at ``_RAMP_FRACTIONS`` of the arc), the one
    closest to the end whose state a Ruckig ramp reaches within conservative
    constant limits is taken: the ramp replaces as little of the rule as it
    can. None if no candidate works.
    """
    arc = path.arc
    c1, arc_length = path.segment_lengths[:2]
    for theta in candidates:
        s, speed, accel = _curvature_state(arc, rate, float(theta))
        span = (c1, c1 + s) if starting else (c1 + s, c1 + arc_length)
        # Room above the node's speed: the rule still speeds up (slows down) there.
        top = speed * 1.25
        bounds = _constant_limits(path, span[0], span[1], top, limits)
        if bounds is None or abs(accel) > bounds[0]:
            continue
        if starting:
            rows = _ruckig_rows((0.0, 0.0, 0.0), (s, speed, accel), top, *bounds)
        else:
            rows = _ruckig_rows((s, speed, accel), (arc_length, 0.0, 0.0), top, *bounds)
        if rows is not None:
            return float(theta), rows
    return None
