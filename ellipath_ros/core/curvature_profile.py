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

Cost: the loops over nodes, samples and panels are compiled kernels
(:mod:`.compiled`); those that decide K and the node list do NumPy's
operations in NumPy's order, so durations and nodes are those of the plain
NumPy formulas bit for bit. A state of the law costs one table look-up, two
polynomials and one sine and cosine (no quadrature or iteration per sample).
"""

from dataclasses import dataclass, field
import functools
import math

import numpy as np

from .compiled import kernel
from .errors import InvalidInputError, LimitError, require_range
from .geometry import ellipse_speed, EllipticArc
from .limits import _ACCEL_MARGIN, _cap_values, _JERK_MARGIN, _SPEED_MARGIN
from .motion import (_cubic_state, _piece_sample_times, _pieces_law, _Sequence,
                     TimedMotion)
from .ruckig_lines import _constant_limits, _line_rows, _ruckig_rows, _straight_motion

# Where a ramp may end, in shares of the arc's parameter range, after the nodes.
_RAMP_FRACTIONS = np.array([1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.2])
# The paper's node list is refused beyond this many nodes (r far too small).
_MAX_NODES = 20000
# Time table of the curvature law: Gauss-Legendre panels over the arc.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_ODE_PANELS = 256
_BASELINE_SAMPLES = 4001
# Near the tightest points, bounds of the states' interpolation panels at this share of
# their distance to the nearest pole of 1/sigma (see _CurvatureArcLaw._hermite_table).
_POLE_STEP = 0.05
# Samples whose speed-cap ratio is within this share of the smallest get their exact arc length
# and speed.
_CAP_SHORTLIST = 1e-6
# Samples of the rule whose screened |v|, |a| or |j| is within this share of the largest get
# their exact values (see _screened_peaks: screened and exact differ by 1.5e-15 of the peak
# at most on 5,127 random arcs of the three arc policies).
_PEAK_SHORTLIST = 1e-9
# Columns of a panel's row of the states' table (see _panel_polynomials).
_PANEL_COLUMNS = 20


@dataclass(frozen=True, eq=False)
class _CurvatureArcLaw:
    """
    The paper's law on the arc: d theta/dt = -K rho(theta), from theta_start down to theta_end.

    With sigma = |dP/dtheta| = sqrt(a**2 sin**2 + b**2 cos**2) and rho = sigma**3 / (a b):
    s' = K sigma**4 / (a b), s'' = -4 K**2 sigma**6 sigma_1 / (a b)**2,
    s''' = 4 K**3 sigma**8 (6 sigma_1**2 + sigma sigma_2) / (a b)**3 (sigma_i: derivatives
    by theta), and t(theta) = (a b / K) * integral of sigma**-3 from theta to theta_start.

    The time table holds t at ``_ODE_PANELS`` even steps of theta (Gauss-Legendre
    quadrature per panel); the duration is its total. For the states it also holds, exact
    at those panel bounds, theta' = -K rho, theta'' = K**2 rho rho_1, s, s' and s'';
    theta(t) and s(t) are quintic Hermite interpolants between them (no quadrature and no
    iteration per sample; the tests bound the error against the quadrature), and s', s''
    and s''' follow from theta(t) in closed form.
    """

    arc: EllipticArc
    rate: float  # K [rad/(m s)]
    s_offset: float  # path length at theta_T1 [m]
    theta_start: float
    theta_end: float
    # The time table's parts that do not depend on K: the panel bounds, |half width| * a b and
    # the quadrature sums of sigma**-3 (from :meth:`at_rate`, else computed).
    _quadrature: tuple = field(default=None, repr=False)
    _edges: np.ndarray = field(init=False, repr=False)
    _times: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        if self._quadrature is None:
            edges = np.linspace(self.theta_start, self.theta_end, _ODE_PANELS + 1)
            # As _elapsed(edges[:-1], edges[1:]) computes it, with the division by K left out.
            half = 0.5 * (edges[1:] - edges[:-1])
            nodes = (0.5 * (edges[1:] + edges[:-1]))[..., None] + half[..., None] * _GL_NODES
            object.__setattr__(self, '_quadrature', (
                edges, np.abs(half) * (self.arc.a * self.arc.b),
                ellipse_speed(self.arc.a, self.arc.b, nodes) ** -3 @ _GL_WEIGHTS))
        edges, scaled_half, sums = self._quadrature
        object.__setattr__(self, '_edges', edges)
        object.__setattr__(self, '_times', np.concatenate(
            ([0.0], np.cumsum(scaled_half / self.rate * sums))))

    def at_rate(self, rate, s_offset):
        """Return the law on the same theta range at another K, reusing the quadrature."""
        return _CurvatureArcLaw(self.arc, rate, s_offset, self.theta_start, self.theta_end,
                                self._quadrature)

    @property
    def duration(self):
        return float(self._times[-1])

    def _elapsed(self, theta_from, theta_to):
        """Return the time from theta_from down to theta_to (elementwise), >= 0."""
        half = 0.5 * (theta_to - theta_from)
        nodes = (0.5 * (theta_to + theta_from))[..., None] + half[..., None] * _GL_NODES
        ab = self.arc.a * self.arc.b
        inverse_cube = ellipse_speed(self.arc.a, self.arc.b, nodes) ** -3
        return np.abs(half) * ab / self.rate * (inverse_cube @ _GL_WEIGHTS)

    @functools.cached_property
    def _hermite_table(self):
        """
        Return the panel bounds t (M,) and the panels' polynomials (:func:`_panel_polynomials`).

        The bounds are those of the time table plus, on a thin ellipse, more near its
        tightest points theta = k pi: 1/sigma has poles at k pi +- i atanh(b/a), and a
        polynomial is accurate over a panel only if the panel is narrow beside its
        distance to the nearest pole. The time at each added bound is that of the time
        table's panel it lies in plus the quadrature from that panel's start (the very
        function the duration sums).
        """
        arc, rate = self.arc, self.rate
        a, b = arc.a, arc.b
        theta, times = self._edges, self._times
        if a > b:
            # sigma**2 = 0 at theta = k pi +- i beta: near k pi, panels as wide as a share
            # of their distance to that pole, up to where the even steps are narrower.
            beta = math.atanh(b / a)
            widest = math.acosh(max(math.pi / (_ODE_PANELS * _POLE_STEP * beta), 1.0))
            offsets = beta * np.sinh(np.arange(0.0, widest, _POLE_STEP))
            turns = np.arange(math.floor(self.theta_end / math.pi),
                              math.ceil(self.theta_start / math.pi) + 1)[:, None] * math.pi
            crossings = np.concatenate(((turns + offsets).ravel(), (turns - offsets).ravel()))
            crossings = crossings[(crossings < self.theta_start) & (crossings > self.theta_end)]
            panel = np.clip(np.searchsorted(-theta, -crossings, side='right') - 1, 0,
                            _ODE_PANELS - 1)
            order = np.argsort(-np.concatenate((theta, crossings)), kind='stable')
            times = np.concatenate((times, times[panel] + self._elapsed(theta[panel], crossings)))[
                order]
            theta = np.concatenate((theta, crossings))[order]
            # A crossing next to a bound may round to before it: keep the times sorted.
            times = np.maximum.accumulate(times)
        s = self.s_offset + arc.s_from_t(arc.t_from_theta(theta))
        panels = np.empty((theta.size - 1, _PANEL_COLUMNS))
        _panel_polynomials(times, theta, s, a, b, rate, panels)
        return times, panels

    def _evaluate(self, t):
        """Return the rows (theta, s, s', s'', s''') at times ``t`` (N,), shape (5, N)."""
        t = np.ascontiguousarray(t, dtype=float)
        out = np.empty((5, t.size))
        _law_states(t, *self._hermite_table, self.arc.a, self.arc.b, self.rate, out)
        return out

    def sample_times(self, count):
        """
        Return sorted times [s]: ``count`` even steps across each panel of the states' table.

        The panels follow the law's own scale (even steps of theta, narrower near the
        tightest points), whatever its duration; within one the law is smooth.
        """
        return _piece_sample_times(self.sample_bounds(), count)

    def sample_bounds(self):
        """Return the times [s] (M,) across which :meth:`sample_times` steps: the panels'."""
        return self._hermite_table[0]

    def theta(self, t):
        """Return theta at times ``t`` (N,) from the start of this law."""
        return self._evaluate(t)[0]

    def state(self, t):
        """Return (s, s', s'', s''') at times ``t`` (N,) from the start of this law."""
        _, s, speed, accel, jerk = self._evaluate(t)
        return s, speed, accel, jerk

    def bounds(self):
        """Return the times [s] (2,) and path lengths [m] (2,) of the law's ends."""
        times = np.array([0.0, self.duration])
        return times, self.state(times)[0]


@kernel
def _sigma_and_rates(theta, a, b):
    """Return sigma, sigma_1, sigma_2 at ``theta`` (as ``geometry.ellipse_sigma`` defines them)."""
    sin_theta, cos_theta = math.sin(theta), math.cos(theta)
    spread = a * a - b * b
    sigma = math.sqrt(a * a * sin_theta * sin_theta + b * b * cos_theta * cos_theta)
    inverse = 1.0 / sigma
    sigma_1 = spread * sin_theta * cos_theta * inverse
    return sigma, sigma_1, (spread * (cos_theta * cos_theta - sin_theta * sin_theta)
                            - sigma_1 * sigma_1) * inverse


@kernel
def _path_factors(a, b, rate):
    """Return K / (a b), -4 K**2 / (a b)**2 and 4 K**3 / (a b)**3 (see :func:`_path_rates`)."""
    ab = a * b
    return rate / ab, -4.0 * rate * rate / (ab * ab), 4.0 * rate * rate * rate / (ab * ab * ab)


@kernel
def _path_rates(sigma, sigma_1, sigma_2, factors):
    """Return s', s'' and s''' of the rule (see the law) from sigma and its derivatives."""
    fourth = sigma * sigma * sigma * sigma
    return (factors[0] * fourth, factors[1] * fourth * sigma * sigma * sigma_1,
            factors[2] * fourth * fourth * (6.0 * sigma_1 * sigma_1 + sigma * sigma_2))


@kernel
def _panel_polynomials(times, theta, s, a, b, rate, out):
    """
    Fill ``out`` (M - 1, ``_PANEL_COLUMNS``) with each panel's theta(x) and s(x), x in [0, 1].

    Columns 0-7 and 8-15: the coefficients of the degree-7 polynomials (x**0 first) with
    value and first three derivatives exact at both bounds (``theta``, ``s`` at
    ``times``, the rates from the rule); 16-19: the smaller and larger bound of theta
    and of s, which the values are kept within.
    """
    ab = a * b
    factors = _path_factors(a, b, rate)
    rates = np.empty((theta.size, 6))
    for index in range(theta.size):
        sigma, sigma_1, sigma_2 = _sigma_and_rates(theta[index], a, b)
        rho = sigma * sigma * sigma / ab
        rho_1 = 3.0 * sigma * sigma * sigma_1 / ab
        rho_2 = (6.0 * sigma * sigma_1 * sigma_1 + 3.0 * sigma * sigma * sigma_2) / ab
        rates[index, 0] = -rate * rho
        rates[index, 1] = rate * rate * rho * rho_1
        rates[index, 2] = -rate * rate * rate * rho * (rho_1 * rho_1 + rho * rho_2)
        rates[index, 3], rates[index, 4], rates[index, 5] = _path_rates(sigma, sigma_1, sigma_2,
                                                                        factors)
    for panel in range(theta.size - 1):
        width = times[panel + 1] - times[panel]
        for column, values, first in ((0, theta, 0), (8, s, 3)):
            start, end = values[panel], values[panel + 1]
            slope_0, slope_1 = rates[panel, first] * width, rates[panel + 1, first] * width
            curve_0 = rates[panel, first + 1] * width * width
            curve_1 = rates[panel + 1, first + 1] * width * width
            third_0 = rates[panel, first + 2] * width * width * width
            third_1 = rates[panel + 1, first + 2] * width * width * width
            jump = end - start
            out[panel, column] = start
            out[panel, column + 1] = slope_0
            out[panel, column + 2] = 0.5 * curve_0
            out[panel, column + 3] = third_0 / 6.0
            out[panel, column + 4] = (35.0 * jump - 20.0 * slope_0 - 15.0 * slope_1
                                      - 5.0 * curve_0 + 2.5 * curve_1
                                      - third_0 * (2.0 / 3.0) - third_1 / 6.0)
            out[panel, column + 5] = (-84.0 * jump + 45.0 * slope_0 + 39.0 * slope_1
                                      + 10.0 * curve_0 - 7.0 * curve_1 + third_0 + 0.5 * third_1)
            out[panel, column + 6] = (70.0 * jump - 36.0 * slope_0 - 34.0 * slope_1
                                      - 7.5 * curve_0 + 6.5 * curve_1
                                      - third_0 * (2.0 / 3.0) - 0.5 * third_1)
            out[panel, column + 7] = (-20.0 * jump + 10.0 * (slope_0 + slope_1)
                                      + 2.0 * (curve_0 - curve_1) + (third_0 + third_1) / 6.0)
        out[panel, 16] = min(theta[panel], theta[panel + 1])
        out[panel, 17] = max(theta[panel], theta[panel + 1])
        out[panel, 18] = min(s[panel], s[panel + 1])
        out[panel, 19] = max(s[panel], s[panel + 1])


@kernel
def _law_states(t, times, panels, a, b, rate, out):
    """
    Fill ``out`` (5, N) with theta, s, s', s'', s''' of the law at times ``t`` (N,).

    ``times`` (M,) are the panel bounds and ``panels`` the rows of
    :func:`_panel_polynomials`. Sorted times (the usual case) find their panel by a
    step from the previous one, others by bisection.
    """
    factors = _path_factors(a, b, rate)
    panel = 0
    for index in range(t.size):
        (out[0, index], out[1, index], out[2, index], out[3, index], out[4, index],
         panel) = _law_state(t[index], times, panels, a, b, factors, panel)


@kernel(inline=True)
def _law_state(t, times, panels, a, b, factors, panel):
    """
    Return theta, s, s', s'', s''' of the law at one time ``t``, and its panel.

    ``times``, ``panels``, ``a`` and ``b`` are as :func:`_law_states` takes them, ``factors``
    is :func:`_path_factors`; the search for the panel starts from ``panel`` (the previous
    time's).
    """
    last = times.size - 2
    now = min(max(t, 0.0), times[last + 1])
    if now < times[panel] or (now >= times[panel + 1] and panel < last):
        panel = min(max(np.searchsorted(times, now, side='right') - 1, 0), last)
    x = (now - times[panel]) / max(times[panel + 1] - times[panel], 1e-300)
    row = panels[panel]
    theta = row[0] + x * (row[1] + x * (row[2] + x * (row[3] + x * (
        row[4] + x * (row[5] + x * (row[6] + x * row[7]))))))
    theta = min(max(theta, row[16]), row[17])
    s = row[8] + x * (row[9] + x * (row[10] + x * (row[11] + x * (
        row[12] + x * (row[13] + x * (row[14] + x * row[15]))))))
    sigma, sigma_1, sigma_2 = _sigma_and_rates(theta, a, b)
    speed, accel, jerk = _path_rates(sigma, sigma_1, sigma_2, factors)
    return theta, min(max(s, row[18]), row[19]), speed, accel, jerk, panel


@dataclass(frozen=True, eq=False)
class _CurvatureSequence(_Sequence):
    """
    The curvature profile's laws: lines and ramps (constant-jerk pieces) and one arc law.

    :meth:`state` evaluates them in one compiled pass (:func:`_sequence_rows`), each time
    by its law's own formulas: the same numbers as :meth:`_Sequence.state`, without a
    Python call per law.
    """

    @functools.cached_property
    def _arrays(self):
        """Return the laws as :func:`_sequence_rows` takes them after ``starts``."""
        arc_law = next(index for index, law in enumerate(self.laws)
                       if isinstance(law, _CurvatureArcLaw))
        arc = self.laws[arc_law]
        pieces = [law for law in self.laws if law is not arc]
        # Each law's share of the pieces' arrays (none for the arc law).
        time_counts = [0 if law is arc else law.times.size for law in self.laws]
        piece_counts = [0 if law is arc else law.jerk.size for law in self.laws]
        piece_rows = np.vstack([np.concatenate([getattr(law, name) for law in pieces])
                                for name in ('s0', 'v0', 'a0', 'jerk')])
        return (np.concatenate([law.times for law in pieces]), piece_rows,
                np.cumsum([0] + time_counts), np.cumsum([0] + piece_counts), arc_law,
                *arc._hermite_table, arc.arc.a, arc.arc.b, arc.rate)

    def state(self, t):
        """Return :meth:`_Sequence.state` at times ``t`` (N,)."""
        t = np.ascontiguousarray(t, dtype=float)
        rows = np.empty((4, t.size))
        _sequence_rows(t, self._starts, *self._arrays, rows)
        return tuple(rows)

    def newton_times(self, lengths, t, factor, duration):
        """Return :meth:`_Sequence.newton_times`, its steps in one compiled pass."""
        t = np.array(t, dtype=float)
        _newton_rows(np.ascontiguousarray(lengths, dtype=float), t, factor, duration,
                     self._starts, *self._arrays)
        return t


@kernel
def _sequence_rows(t, starts, piece_times, piece_rows, first_times, first_pieces, arc_law,
                   arc_times, arc_panels, a, b, rate, rows):
    """
    Fill ``rows`` (4, N) with s, s', s'', s''' of a :class:`_CurvatureSequence` at ``t`` (N,).

    A time's law is the last starting at or before it (the first for earlier times);
    ``starts`` (L + 1,) are the laws' starts and the end. The constant-jerk laws' arrays
    are concatenated: law i has ``piece_times[first_times[i]:first_times[i + 1]]`` and
    the columns ``first_pieces[i]:first_pieces[i + 1]`` of ``piece_rows`` (s0, v0, a0,
    jerk); law ``arc_law`` is the arc law, with the arrays :func:`_law_states` takes.
    Each is evaluated at the time from its start, by its own formulas. The loop calls
    each law's step itself: a step inlined into an inlined step pays the reference
    counts of the arrays it takes on every sample (this loop took twice the time so).
    """
    factors = _path_factors(a, b, rate)
    panel = 0
    for index in range(t.size):
        law = min(max(np.searchsorted(starts, t[index], side='right') - 1, 0), starts.size - 2)
        x = t[index] - starts[law]
        if law == arc_law:
            _, s, speed, accel, jerk, panel = _law_state(x, arc_times, arc_panels, a, b, factors,
                                                         panel)
        else:
            s, speed, accel, jerk = _law_piece_state(
                piece_times, first_times[law], first_times[law + 1], piece_rows,
                first_pieces[law], first_pieces[law + 1], x)
        rows[0, index], rows[1, index], rows[2, index], rows[3, index] = s, speed, accel, jerk


@kernel(inline=True)
def _law_piece_state(piece_times, first_time, end_time, piece_rows, first_piece, end_piece, t):
    """
    Return :func:`~ellipath_ros.core.motion._piece_state` of one constant-jerk law at ``t``.

    The law is ``piece_times[first_time:end_time]`` and the columns
    ``first_piece:end_piece`` of ``piece_rows`` (s0, v0, a0, jerk), read in place, not
    through slices (views, with reference counts). The piece is found by numba's
    bisection of ``np.searchsorted(times, t, side='right')`` on that range (a NaN ``t``
    is after every time): the same piece, and the same arithmetic.
    """
    low, high = first_time, end_time
    while low < high:
        middle = low + ((high - low) >> 1)
        if math.isnan(t) or piece_times[middle] <= t:
            low = middle + 1
        else:
            high = middle
    index = min(max(low - first_time - 1, 0), end_piece - first_piece - 1)
    column = first_piece + index
    return _cubic_state(t - piece_times[first_time + index], piece_rows[0, column],
                        piece_rows[1, column], piece_rows[2, column], piece_rows[3, column])


@kernel
def _newton_rows(lengths, t, factor, duration, starts, piece_times, piece_rows, first_times,
                 first_pieces, arc_law, arc_times, arc_panels, a, b, rate):
    """
    Refine ``t`` (N,) in place: :meth:`_Sequence.newton_times` towards ``lengths`` (N,).

    The sequence is :func:`_sequence_rows`' arrays, slowed down by ``factor``, as
    :meth:`~ellipath_ros.core.motion.TimedMotion.path_state` reads it: all times clipped to
    [0, ``duration``] when one is outside, divided by ``factor``, s' divided by ``factor``
    unless it is 1; NumPy's clip (the larger of the value and 0, then the smaller of that
    and the duration) on each step.
    """
    law_times, rows = np.empty(t.size), np.empty((4, t.size))
    for _ in range(3):
        outside = False
        for index in range(t.size):
            outside = outside or t[index] < 0.0 or t[index] > duration
        for index in range(t.size):
            law_times[index] = (_clipped(t[index], duration) if outside else t[index]) / factor
        _sequence_rows(law_times, starts, piece_times, piece_rows, first_times, first_pieces,
                       arc_law, arc_times, arc_panels, a, b, rate, rows)
        for index in range(t.size):
            speed = rows[1, index] / factor if factor != 1.0 else rows[1, index]
            if speed > 1e-9:
                t[index] = _clipped(t[index] - (rows[0, index] - lengths[index]) / speed,
                                    duration)


@kernel(inline=True)
def _clipped(value, high):
    """Return ``np.clip(value, 0.0, high)`` of a float as NumPy computes it."""
    value = value if value > 0.0 else 0.0
    return value if value < high else high


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
    return _nodes_and_unit_law(arc, r)[0]


def _nodes_and_unit_law(arc, r):
    """Return :func:`curvature_nodes` and the law at K = 1 over the arc it estimates with."""
    r = require_range('r', r, 0.0, math.inf, low_open=True, unit='rad/m')
    # Node count ~ integral of dtheta / (r rho): refuse huge lists before building them.
    law = _CurvatureArcLaw(arc, 1.0, 0.0, arc.theta_T1, arc.theta_T2)
    estimate = law.duration / r
    if estimate > _MAX_NODES:
        raise InvalidInputError(
            f'r: expected a value giving at most {_MAX_NODES} nodes (r >= '
            f'{law.duration / _MAX_NODES:.3g} rad/m for this arc), got {r!r} rad/m')
    # Room for the Euler steps' count (near the estimate); more if they take more.
    nodes = np.empty(int(estimate * 1.5) + 16)
    count = _node_steps(arc.theta_T1, arc.theta_T2, arc.a, arc.b, r, 2.0, nodes)
    while count > nodes.size:
        nodes = np.empty(2 * nodes.size)
        count = _node_steps(arc.theta_T1, arc.theta_T2, arc.a, arc.b, r, 2.0, nodes)
    nodes = nodes[:count]
    nodes[-1] = arc.theta_T2
    return nodes, law


@kernel
def _node_steps(theta_start, theta_end, a, b, r, square, out):
    """
    Write the nodes theta_{i+1} = theta_i - r rho(theta_i) from theta_start past theta_end.

    Returns their count, or more than ``out`` holds if it is too short (then the
    list is incomplete). rho is computed as ``EllipticArc.radius_of_curvature``
    computes it on a scalar (libm's sin, cos and pow), so the nodes are those of
    that function bit for bit. ``square`` is 2.0, passed at run time: NumPy's scalar
    ``x ** 2`` calls pow, which is not always x * x, and a constant exponent would
    let the compiler substitute x * x.
    """
    ab = a * b
    theta = theta_start
    out[0] = theta
    count = 1
    while theta > theta_end:
        if count == out.size:
            return count + 1
        sigma = math.sqrt(a * a * math.pow(math.sin(theta), square)
                          + b * b * math.pow(math.cos(theta), square))
        theta -= r * (math.pow(sigma, 3.0) / ab)
        out[count] = theta
        count += 1
    return count


def _arc_cartesian_peaks(arc, theta):
    """
    Return |v|, |a|, |j| of the rule with K = 1 at ``theta`` (paper frame), and sigma, sigma'.

    Each (N,); computed as NumPy computes the same formulas (see :func:`_rule_sample`).
    """
    out = np.empty((5, theta.size))
    _rule_norms(np.ascontiguousarray(theta, dtype=float), arc.a, arc.b, arc.l, arc.h, arc.k,
                arc.theta_T2, out)
    return out


def _rule_peaks(arc, theta):
    """
    Return the largest |v|, |a|, |j| of the rule with K = 1 at ``theta``, and more rows.

    The peaks (4,), and |v| at ``theta[0]`` last, are :func:`_arc_cartesian_peaks`' bit for
    bit (:func:`_screened_peaks`); the rows (3, N) are |v| within rounding (to shortlist
    by), sigma and sigma' (exact).
    """
    peaks, rows = np.empty(4), np.empty((3, theta.size))
    _screened_peaks(np.ascontiguousarray(theta, dtype=float), arc.a, arc.b, arc.l, arc.h,
                    arc.k, arc.theta_T2, peaks, rows)
    return peaks, rows


@kernel
def _rule_norms(theta, a, b, l_, h, k, theta_t2, out):
    """Fill ``out`` (5, N) with :func:`_rule_sample` at each of ``theta`` (N,), exactly."""
    for index in range(theta.size):
        angle = theta[index]
        t = angle - theta_t2
        (out[0, index], out[1, index], out[2, index], out[3, index],
         out[4, index]) = _rule_sample(math.sin(angle), math.cos(angle), math.sin(t),
                                       math.cos(t), a, b, l_, h, k, True)


@kernel
def _screened_peaks(theta, a, b, l_, h, k, theta_t2, peaks, rows):
    """
    Fill ``peaks`` (4,) with the largest |v|, |a|, |j| at ``theta`` (N,) and |v| at its first.

    All as :func:`_rule_norms` gives them, at under half its cost: every sample is screened
    with products for libm's pow (x * x * x) and the sine and cosine of the paper frame's
    parameter t = theta - theta_T2 from theta's (a few units in the last place apart; the
    two pow calls cost more than the rest of a sample), and only the first and those within
    ``_PEAK_SHORTLIST`` of a screened peak are computed exactly: the exact peak's sample is
    among them. ``rows`` (3, N) gets the screened |v|, and sigma and sigma' (exact: the
    same operations either way).
    """
    sin_end, cos_end = math.sin(theta_t2), math.cos(theta_t2)
    screened = np.empty((3, theta.size))
    for index in range(theta.size):
        sin_theta, cos_theta = math.sin(theta[index]), math.cos(theta[index])
        (screened[0, index], screened[1, index], screened[2, index], rows[1, index],
         rows[2, index]) = _rule_sample(
            sin_theta, cos_theta, sin_theta * cos_end - cos_theta * sin_end,
            cos_theta * cos_end + sin_theta * sin_end, a, b, l_, h, k, False)
    bars = np.empty(3)
    for row in range(3):
        bars[row] = screened[row].max() * (1.0 - _PEAK_SHORTLIST)
    peaks[:] = 0.0
    for index in range(theta.size):
        rows[0, index] = screened[0, index]
        if (index > 0 and screened[0, index] < bars[0] and screened[1, index] < bars[1]
                and screened[2, index] < bars[2]):
            continue
        angle = theta[index]
        t = angle - theta_t2
        speed, accel, jerk, _, _ = _rule_sample(math.sin(angle), math.cos(angle), math.sin(t),
                                                math.cos(t), a, b, l_, h, k, True)
        if index == 0:
            peaks[3] = speed
        peaks[0], peaks[1], peaks[2] = (max(peaks[0], speed), max(peaks[1], accel),
                                        max(peaks[2], jerk))


@kernel(inline=True)
def _rule_sample(sin_theta, cos_theta, sin_t, cos_t, a, b, l_, h, k, exact):
    """
    Return |v|, |a|, |j| of the rule with K = 1, sigma and sigma' at one theta.

    Given the sine and cosine of theta and of the paper frame's t = theta - theta_T2.

    theta' = -rho, theta'' = rho rho_1, theta''' = -rho (rho_1**2 + rho rho_2) for K = 1;
    d2P/dtheta2 = -P and d3P/dtheta3 = -dP/dtheta (ellipse about its centre). With
    ``exact``, the operations are those of ``geometry.radius_of_curvature_derivatives``,
    ``EllipticArc.point`` and ``derivative`` and ``numpy.linalg.norm``, in their order, with
    libm's sin, cos and pow: the same numbers bit for bit; without, the two cubes are
    products.
    """
    spread, ab = a * a - b * b, a * b
    sigma = math.sqrt(a * a * math.pow(sin_theta, 2.0) + b * b * math.pow(cos_theta, 2.0))
    sigma_1 = spread * sin_theta * cos_theta / sigma
    sigma_2 = (spread * (math.pow(cos_theta, 2.0) - math.pow(sin_theta, 2.0))
               - math.pow(sigma_1, 2.0)) / sigma
    rho = (math.pow(sigma, 3.0) if exact else sigma * sigma * sigma) / ab
    rho_1 = 3.0 * math.pow(sigma, 2.0) * sigma_1 / ab
    rho_2 = (6.0 * sigma * math.pow(sigma_1, 2.0) + 3.0 * math.pow(sigma, 2.0) * sigma_2) / ab
    w1, w2 = -rho, rho * rho_1
    w3 = -rho * (math.pow(rho_1, 2.0) + rho * rho_2)
    px, py = l_ * cos_t, h * cos_t + k * sin_t
    dx, dy = -l_ * sin_t, -h * sin_t + k * cos_t
    vx, vy = dx * w1, dy * w1
    square, product = math.pow(w1, 2.0), w1 * w2
    cube = math.pow(w1, 3.0) if exact else w1 * w1 * w1
    ax, ay = -px * square + dx * w2, -py * square + dy * w2
    jx = -dx * cube - 3.0 * px * product + dx * w3
    jy = -dy * cube - 3.0 * py * product + dy * w3
    return (math.sqrt(vx * vx + vy * vy), math.sqrt(ax * ax + ay * ay),
            math.sqrt(jx * jx + jy * jy), sigma, sigma_1)


def _cap_rate(path, speed_cap, theta, speed, sigma, sigma_1):
    """
    Return the largest K the speed cap allows at the samples ``theta``: min cap(s) / speed.

    The arc length of every sample by quadrature (``s_from_t``) would cost more than
    the rest of the profile: the corrected trapezoid rule on the samples' own sigma
    and sigma' (error ~h**4, far below 1e-9 m) and ``speed`` (the rule's |v| at K = 1,
    within rounding: :func:`_rule_peaks`) shortlist the samples within
    ``_CAP_SHORTLIST`` of the smallest ratio, and only those are computed exactly (their
    arc length and |v|, :func:`_arc_cartesian_peaks`), so the result is the exact minimum,
    the same number as over all samples.
    """
    arc = path.arc
    c1 = path.segment_lengths[0]
    lengths = np.empty(theta.size)
    _trapezoid_lengths(theta, sigma, sigma_1, c1, lengths)
    ratio = _cap_values(speed_cap, lengths) / speed
    shortlist = theta[ratio <= ratio.min() * (1.0 + _CAP_SHORTLIST)]
    s = c1 + arc.s_from_t(arc.t_from_theta(shortlist))
    return float(np.min(_cap_values(speed_cap, s) / _arc_cartesian_peaks(arc, shortlist)[0]))


@kernel
def _trapezoid_lengths(theta, sigma, sigma_1, start, out):
    """
    Fill ``out`` (N,) with ``start`` plus the arc length at ``theta`` (N,) by :func:`_cap_rate`.

    The corrected trapezoid rule on ``sigma`` and ``sigma_1`` summed from the first
    sample, with the operations (and order) of the NumPy formula ``start +
    concatenate(([0], cumsum(0.5 step (sigma_i + sigma_i+1) - step**2 / 12 (sigma_1,i -
    sigma_1,i+1))))``: the same lengths bit for bit, in one pass.
    """
    out[0] = start + 0.0
    total = 0.0
    for index in range(theta.size - 1):
        step = theta[index] - theta[index + 1]
        piece = (0.5 * step * (sigma[index] + sigma[index + 1])
                 - step * step / 12.0 * (sigma_1[index] - sigma_1[index + 1]))
        total = piece if index == 0 else total + piece
        out[index + 1] = start + total


def _curvature_state(arc, rate, theta):
    """Return (s from T1 [m], s', s'') of the rule at a scalar ``theta``."""
    return (float(arc.s_from_t(arc.t_from_theta(theta))),) + _curvature_rates(arc, rate, theta)


def _rule_speed(arc, rate, theta):
    """Return s' = K sigma**4 / (a b) at a scalar ``theta``, as the law's states on arrays did."""
    return float((rate * ellipse_speed(arc.a, arc.b, np.array([theta])) ** 4 / (arc.a * arc.b))[0])


def _curvature_rates(arc, rate, theta):
    """
    Return s' and s'' of the rule at a scalar ``theta``.

    sigma and sigma' as ``geometry.ellipse_sigma`` computes them, on floats (libm's
    sin, cos and pow, as NumPy's): the same numbers without NumPy's per-call cost.
    """
    a, b = arc.a, arc.b
    ab = a * b
    sin_theta, cos_theta = math.sin(theta), math.cos(theta)
    sigma = math.sqrt(a * a * sin_theta ** 2 + b * b * cos_theta ** 2)
    sigma_1 = (a * a - b * b) * sin_theta * cos_theta / sigma
    return rate * sigma ** 4 / ab, -4.0 * rate ** 2 * sigma ** 6 * sigma_1 / ab ** 2


def _curvature_motion(path, limits, r, speed_cap):
    """Build the paper's profile (module docstring): the rule on the arc, Ruckig elsewhere."""
    if path.arc is None:
        return _straight_motion(path, limits, speed_cap, 'curvature')
    arc = path.arc
    nodes, unit_law = _nodes_and_unit_law(arc, r)
    # The tightest point (theta = 0 mod pi) is sampled exactly.
    theta = np.linspace(arc.theta_T1, arc.theta_T2, _BASELINE_SAMPLES)
    theta = np.sort(np.append(theta, math.pi * math.ceil(arc.theta_T2 / math.pi)))[::-1]
    (peak_speed, peak_accel, peak_jerk, first_speed), (speed, sigma, sigma_1) = _rule_peaks(
        arc, theta)
    rate = min(limits.max_speed * _SPEED_MARGIN / peak_speed,
               math.sqrt(limits.max_accel * _ACCEL_MARGIN / peak_accel),
               (limits.max_jerk * _JERK_MARGIN / peak_jerk) ** (1.0 / 3.0))
    if speed_cap is not None:
        rate = min(rate, _SPEED_MARGIN * _cap_rate(path, speed_cap, theta, speed, sigma,
                                                   sigma_1))
    # Step at T1/T2: s'**2 / rho_T <= max_accel_jump, s' = K u_T (same u at both ends). When
    # that would slow the whole arc down, the arc starts and ends at rest (ramps) instead.
    ramps = math.sqrt(limits.max_accel_jump * arc.end_radius) / first_speed < rate
    # The entry and exit states scale with K: shrink it until the lines (or ramps) fit.
    groups = None
    for _ in range(40):
        groups = _curvature_groups(path, limits, speed_cap, nodes, rate, ramps, unit_law)
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
        # Where a ramp starts (ends) the arc, s' = 0 there exactly. Else the rule's speed at the
        # law's bounds, in closed form.
        first_arc, last_arc = groups[1][0], groups[1][-1]
        if path.segment_lengths[0] > 0.0:
            v_t1 = _rule_speed(arc, rate, first_arc.theta_start)
        if path.segment_lengths[2] > 0.0:
            v_t2 = _rule_speed(arc, rate, last_arc.theta_end)
    law = _CurvatureSequence(laws)
    return TimedMotion(path, 'curvature', law.duration, segments,
                       v_t1 ** 2 / arc.end_radius, v_t2 ** 2 / arc.end_radius,
                       int(nodes.size), law, node_period=r / rate)


def _curvature_groups(path, limits, speed_cap, nodes, rate, ramps, unit_law):
    """
    Return (lift laws, arc laws, descent laws) for the rule at rate K, or None if none fit.

    The arc starts (ends) at rest with a ramp when its clearance is 0 or
    ``ramps`` is set; the line then runs from rest to rest. ``unit_law`` (K = 1
    over the whole arc) lends its quadrature to a law on the same range.
    """
    arc = path.arc
    c1, arc_length, c2 = path.segment_lengths
    count = nodes.size
    lift, descent, arc_laws = [], [], []
    theta_start, theta_end = arc.theta_T1, arc.theta_T2
    ramp_in = ramp_out = None
    if c1 > 0.0:
        entry = (0.0, 0.0) if ramps else _curvature_rates(arc, rate, theta_start)
        rows = _line_rows((0.0, 0.0, 0.0), (c1, entry[0], entry[1]), limits, speed_cap,
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
    if (theta_start, theta_end) == (unit_law.theta_start, unit_law.theta_end):
        arc_laws.append(unit_law.at_rate(rate, c1))
    else:
        arc_laws.append(_CurvatureArcLaw(arc, rate, c1, theta_start, theta_end))
    if ramp_out is not None:
        arc_laws.append(_pieces_law(ramp_out[1], c1))
    if c2 > 0.0:
        exit_state = (0.0, 0.0) if ramps else _curvature_rates(arc, rate, theta_end)
        rows = _line_rows((c1 + arc_length, exit_state[0], exit_state[1]),
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
