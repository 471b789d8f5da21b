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
The paper's path: an asymmetric bisected ellipse between two vertical segments.

Paper frame (also used by docs/paper_reproduction.md): the vertical plane
through pick and place, coordinates (x, y) = (horizontal along ``u``,
vertical), origin at the midpoint of the tangent points, T1 = (-l, -h),
T2 = (l, h), l > 0.

Every ellipse through T1 and T2 with vertical tangents there has its centre at
the origin, so the family has one parameter. We use the conjugate
semi-diameter form::

    P(t) = cos(t) * (l, h) + sin(t) * (0, k),    k > 0,  t from pi (T1) to 0 (T2)

which is continuous in h and has no 0/0. The paper's quantities follow from
(l, h, k): the axes a >= b are the singular values of [[l, 0], [h, k]], phi is
the direction of the major axis, and the paper's parameter is
theta = t + theta_T2 (eq. 29). Closed forms used below: the radius of curvature
at T1 and T2 is k**2 / l, the apex is at height sqrt(h**2 + k**2) and the
smallest radius of curvature on the arc is b**2 / a (every half ellipse
contains one end of the major axis).

Joins (``join``): the paper's path (``'paper'``) goes straight from a vertical
line (curvature 0) into the ellipse (curvature 1/rho_T), a curvature step. The
``'g2'`` join (:class:`BlendedArc`) keeps the vertical lines whole and bends
the first and last stretch of the ellipse horizontally by a polynomial in its
parameter, so that the curvature rises continuously from 0 at T1 (falls to 0
at T2) and the path stays within ``join_tolerance`` of the paper's.
"""

from dataclasses import dataclass, field
import functools
import math

import numpy as np

from .compiled import kernel
from .errors import DegenerateGeometryError, InvalidInputError, require_point, require_range
from .settings import default_of, validate, validate_fields

ARC_POLICIES = ('paper', 'apex_clearance', 'min_radius')
# How the vertical lines meet the arc: a curvature-continuous transition, or the paper's step.
JOINS = ('g2', 'paper')
DEFAULT_JOIN_TOLERANCE = default_of('join_tolerance')
# -- G2 transition design (issue 14; scripts/join_study.py measures the choices) ----------
# Largest value of the transition shape f(u) = u**2 (1 - u)**4 / 2 on [0, 1] (at u = 1/3).
_BLEND_PEAK = 8.0 / 729.0
# Each transition is the longest whose curve stays within the tolerance of the ellipse, found
# in a few rescaling steps from the closed-form horizontal bound (within the caps below) to a
# relative precision. The distance used is an upper bound: to the ellipse point reached by
# Newton steps from the same parameter, sampled with a margin for what lies between samples.
_BLEND_SPAN_STEPS = 8
_BLEND_SPAN_PRECISION = 1e-3
_BLEND_DISTANCE_SAMPLES = 201
_BLEND_DISTANCE_MARGIN = 2e-3
_BLEND_FOOT_STEPS = 4
# A transition spans at most this share of the arc's parameter on its side of the apex...
_BLEND_APEX_SHARE = 0.8
# ... and at most this much of the parameter range [0, pi] (the two never overlap).
_BLEND_MAX_SPAN = 0.45 * math.pi
# The bent curve must keep at least this share of the ellipse's smallest parameter speed.
_BLEND_MIN_SPEED_SHARE = 0.2
# An upper bound on |f'(u)| on [0, 1] for the shape f of _blend_shape (0.052353 at u = 0.1225).
_BLEND_SLOPE_BOUND = 0.0524
# On tight, lopsided arcs a long transition bends the other way for a while (a slight S,
# which the timing crawls through): such a span is halved until its curvature keeps its
# sign on this many samples, then bisected this often towards the longest one that does.
_BLEND_SIGN_SAMPLES = 257
_BLEND_SIGN_HALVINGS = 20
_BLEND_SIGN_BISECTIONS = 10
_DENSE_SAMPLES = 4097

# As phi* nears the critical angle the paper's ellipse collapses onto the chord T1-T2
# (k -> 0): the arc rises only k above the chord's midpoint, its radius at T1 and T2 is
# k**2 / l and its smallest radius b**2 / a <= k**2 / l. Below this bulge k / l (radius at
# the tangent points under l / 100) the paper's rule takes the next whole degree. Near the
# paper's 10 deg example this is the margin of about 0.1 deg used before; unlike a fixed
# margin it scales with the angle, so every sound paper ellipse is kept (e.g. phi* = 1 deg
# at a 0.94 deg critical angle: k / l = 0.25). See docs/paper_reproduction.md, erratum 3.
_PAPER_MIN_BULGE = 0.1
# Horizontal distances below this are a straight move from pick to place (no arc): any
# ellipse over so short a width is a needle whose corners no robot can follow.
_MIN_HORIZONTAL_DISTANCE = 1e-3
# An arc whose smallest radius of curvature is below this is rejected: a needle-thin ellipse,
# whose ends allow at most sqrt(50 m/s**2 * 0.05 mm) = 5 cm/s at the default acceleration limit.
_MIN_ARC_RADIUS = 5e-5
# Coordinates beyond this are no robot's workspace (and would overflow the arithmetic).
_MAX_COORDINATE = 10.0
# Pick and place closer than this are the same point: nothing to plan.
_MIN_MOVE_DISTANCE = 1e-6

# 8-point Gauss-Legendre nodes and weights on [-1, 1], for the arc-length quadratures (the
# speed of an ellipse is smooth: 8 nodes per panel reach full double precision).
GAUSS_LEGENDRE_NODES, GAUSS_LEGENDRE_WEIGHTS = np.polynomial.legendre.leggauss(8)
# Panels of the arc-length table over t in [0, pi].
_N_PANELS = 256


@dataclass(frozen=True)
class ArcPolicy:
    """
    How the ellipse is chosen among those tangent to both verticals.

    Attributes
    ----------
    kind : str
        ``'paper'``: the paper's rule, phi* = the whole degree at or above the
        critical angle atan(|h| / l) (regularised, see ``paper_phi``).
        ``'apex_clearance'``: the apex stands ``apex_clearance`` above the
        higher tangent point; works for any geometry, equal heights included.
        ``'min_radius'``: the shortest arc whose smallest radius of curvature is
        at least ``min_radius``.
    apex_clearance : float
        Apex height above the higher tangent point [m], used by
        ``'apex_clearance'``; in (0, 2].
    min_radius : float
        Smallest admissible radius of curvature [m], used by ``'min_radius'``;
        in (0, 2].

    """

    kind: str = default_of('arc_policy')
    apex_clearance: float = default_of('apex_clearance')
    min_radius: float = default_of('min_radius')

    def __post_init__(self):
        validate_fields(self)


def paper_phi(half_width, h):
    """
    Return the paper's optimal angle phi* [rad] (eq. 18), regularised.

    phi* = ceil(critical angle in degrees), mirrored for h < 0. Where that
    ellipse is collapsed onto the chord T1-T2 (a critical angle on or just
    below a whole degree: k / l below ``_PAPER_MIN_BULGE``), the next whole
    degree is taken. h = 0 returns 0 (the paper's 0/0, whose limit from
    either side is the semicircle).

    Raises
    ------
    DegenerateGeometryError
        If the rule leaves no ellipse (phi* would reach 90 degrees).

    """
    if h == 0.0:
        return 0.0
    critical_deg = math.degrees(math.atan2(abs(h), half_width))
    phi_deg = math.ceil(critical_deg)
    min_k_squared = (_PAPER_MIN_BULGE * half_width) ** 2
    if phi_deg < 90 and (
            _conjugate_k_squared(half_width, h, math.radians(phi_deg)) < min_k_squared):
        phi_deg += 1
    if phi_deg >= 90:
        raise DegenerateGeometryError(
            f'paper arc rule: expected a whole degree below 90 deg whose ellipse is not '
            f'collapsed onto the chord (k/l >= {_PAPER_MIN_BULGE:g}), got a critical angle '
            f'atan(|h|/l) of {critical_deg:.4f} deg (l = {half_width:.6g} m, h = {h:.6g} m); '
            f'use the apex_clearance or min_radius arc policy for steep moves')
    return math.copysign(math.radians(phi_deg), h)


def conjugate_k_from_phi(half_width, h, phi):
    """
    Return k of the tangent ellipse whose major axis makes the angle ``phi``.

    From tan(2 phi) = 2 l h / (l**2 - h**2 - k**2), l = ``half_width``; phi = 0
    with h = 0 gives the semicircle k = l.
    """
    if h == 0.0:
        return half_width
    k_squared = _conjugate_k_squared(half_width, h, phi)
    if not k_squared > 0.0:
        raise DegenerateGeometryError(
            f'phi: expected an angle beyond the critical angle '
            f'{math.degrees(math.atan2(abs(h), half_width)):.4f} deg, '
            f'got {math.degrees(phi):.4f} deg')
    return math.sqrt(k_squared)


def _conjugate_k_squared(half_width, h, phi):
    """Return k**2 from tan(2 phi) = 2 l h / (l**2 - h**2 - k**2); <= 0 if phi is too flat."""
    return (half_width * half_width - h * h
            - 2.0 * half_width * abs(h) / math.tan(2.0 * abs(phi)))


def elliptic_e(m):
    """Complete elliptic integral of the second kind E(m), by the AGM (full precision)."""
    a, b = 1.0, math.sqrt(1.0 - m)
    c_squared_sum = 0.5 * m
    power = 0.5
    # The AGM converges quadratically; the bound only guards against rounding cycles.
    for _ in range(64):
        if abs(a - b) <= 2e-16 * a:
            break
        c = 0.5 * (a - b)
        a, b = 0.5 * (a + b), math.sqrt(a * b)
        power *= 2.0
        c_squared_sum += power * c * c
    return math.pi / (2.0 * a) * (1.0 - c_squared_sum)


def ellipse_sigma(a, b, theta):
    """
    Return sigma = |dP/dtheta| and its first two derivatives by theta, each shaped as theta.

    The ellipse calculus of the paper's parameter theta (eq. 29) in one place:
    sigma = sqrt(a**2 sin**2 theta + b**2 cos**2 theta) (the speed of the
    ellipse in theta), sigma' = (a**2 - b**2) sin theta cos theta / sigma,
    sigma'' = ((a**2 - b**2) cos 2 theta - sigma'**2) / sigma [m/rad, m/rad**2,
    m/rad**3]; the radius of curvature is sigma**3 / (a b) (eq. 34).
    """
    theta = np.asarray(theta, dtype=float)
    spread = a * a - b * b
    sin_theta, cos_theta = np.sin(theta), np.cos(theta)
    sigma = _sigma_of(a, b, sin_theta, cos_theta)
    sigma_1 = spread * sin_theta * cos_theta / sigma
    sigma_2 = (spread * (cos_theta ** 2 - sin_theta ** 2) - sigma_1 ** 2) / sigma
    return sigma, sigma_1, sigma_2


def ellipse_speed(a, b, theta):
    """Return sigma = |dP/dtheta| alone, as :func:`ellipse_sigma` computes it [m/rad]."""
    theta = np.asarray(theta, dtype=float)
    return _sigma_of(a, b, np.sin(theta), np.cos(theta))


def _sigma_of(a, b, sin_theta, cos_theta):
    """Return sigma from sin theta and cos theta (arrays)."""
    return np.sqrt(a * a * sin_theta ** 2 + b * b * cos_theta ** 2)


def radius_of_curvature_derivatives(a, b, theta):
    """
    Return rho(theta) of the paper's eq. (34) and its first two derivatives.

    Parameters
    ----------
    a, b : float
        Semi-axes of the ellipse [m], > 0.
    theta : numpy.ndarray
        Ellipse parameter (eq. 29) [rad], any shape.

    Returns
    -------
    rho, rho_1, rho_2 : numpy.ndarray
        rho [m], d rho / d theta [m/rad] and d2 rho / d theta2 [m/rad**2],
        shape of ``theta``: rho = sigma**3 / (a b) (:func:`ellipse_sigma`).

    """
    sigma, sigma_1, sigma_2 = ellipse_sigma(a, b, theta)
    ab = a * b
    return (sigma ** 3 / ab, 3.0 * sigma ** 2 * sigma_1 / ab,
            (6.0 * sigma * sigma_1 ** 2 + 3.0 * sigma ** 2 * sigma_2) / ab)


@kernel
def _blend_shape(u):
    """
    Return f(u) = u**2 (1 - u)**4 / 2 and its first three derivatives, u in [0, 1] (float).

    f(0) = f'(0) = 0, f''(0) = 1 and f = f' = f'' = f''' = 0 at u = 1:
    subtracted from the ellipse with the right scale it cancels the curvature
    at the vertical line and vanishes to third order where it meets the
    ellipse (curvature and its rate continuous there). Every polynomial with
    the conditions at 0 and f = f' = f'' = 0 at 1 is
    u**2 (1 - u)**3 (1/2 + p1 u + p2 u**2 + ...); this one is p1 = -1/2,
    p2 = 0. Gentler starts on longer spans, u**2 (1 - u)**n (1/2 + p u) with
    n = 5 or 6, p = 1/2 to 5/4, are up to 1.5 % faster on the bench cycles and
    on most random legs, but trip the time-optimal scan on some lopsided
    approach legs (whole requests up to 1.9 times as long): see
    scripts/join_study.py and the README's Joins section.
    """
    return (u * u * (1.0 + u * (-4.0 + u * (6.0 + u * (-4.0 + u)))) / 2.0,
            u * (1.0 + u * (-6.0 + u * (12.0 + u * (-10.0 + 3.0 * u)))),
            1.0 + u * (-12.0 + u * (36.0 + u * (-40.0 + 15.0 * u))),
            -12.0 + u * (72.0 + u * (-120.0 + 60.0 * u)))


# -- The bend evaluated on plain floats: one compiled form of each formula --------------------
# A bend is (l, h, k, span_1, span_2): the ellipse P(t) = cos t (l, h) + sin t (0, k) and its
# transitions (:class:`BlendedArc`); spans of 0 are the plain ellipse (:class:`EllipticArc`).

@kernel
def _offset_at(l_, span_1, span_2, t):
    """Return the transitions' horizontal offset delta and its derivatives by t at ``t``."""
    delta, delta_1, delta_2, delta_3 = 0.0, 0.0, 0.0, 0.0
    # d/dt = -(1/span) d/du near T1 (u grows as t falls), +(1/span) d/du near T2. Outside a
    # transition no division: x >= span > 0 gives x / span >= 1 (the quotient is rounded
    # monotonically), so u < 1 needs x < span.
    if span_1 > 0.0 and math.pi - t < span_1:
        u = (math.pi - t) / span_1
        if u < 1.0:
            f, f1, f2, f3 = _blend_shape(u)
            delta = -l_ * span_1 * span_1 * f
            delta_1 = l_ * span_1 * f1
            delta_2 = -l_ * f2
            delta_3 = l_ * f3 / span_1
    if span_2 > 0.0 and t < span_2:
        u = t / span_2
        if u < 1.0:
            f, f1, f2, f3 = _blend_shape(u)
            delta = l_ * span_2 * span_2 * f
            delta_1 = l_ * span_2 * f1
            delta_2 = l_ * f2
            delta_3 = l_ * f3 / span_2
    return delta, delta_1, delta_2, delta_3


@kernel
def _ellipse_at(l_, h, k, t):
    """Return x, y, dx/dt, dy/dt of the ellipse at ``t`` (d2P/dt2 = -P, d3P/dt3 = -dP/dt)."""
    return _ellipse_from(l_, h, k, math.cos(t), math.sin(t))


@kernel
def _ellipse_from(l_, h, k, cos_t, sin_t):
    """Return :func:`_ellipse_at` from the cosine and sine of t."""
    return l_ * cos_t, h * cos_t + k * sin_t, -l_ * sin_t, k * cos_t - h * sin_t


@kernel
def _bend_at(l_, h, k, span_1, span_2, t):
    """Return x, y and their first three derivatives by t of the bend at ``t``."""
    return _bend_from(l_, h, k, span_1, span_2, t, math.cos(t), math.sin(t))


@kernel
def _bend_from(l_, h, k, span_1, span_2, t, cos_t, sin_t):
    """
    Return :func:`_bend_at` at ``t`` from its cosine and sine.

    On a grid shared by every curve (:func:`_dense_table`, :func:`_panel_table`) these are
    computed once, by the same libm calls: the same values without their cost per curve.
    """
    x, y, x1, y1 = _ellipse_from(l_, h, k, cos_t, sin_t)
    delta, delta_1, delta_2, delta_3 = _offset_at(l_, span_1, span_2, t)
    return x + delta, y, x1 + delta_1, y1, delta_2 - x, -y, delta_3 - x1, -y1


@kernel
def _speed_at(l_, h, k, span_1, span_2, t):
    """Return |dQ/dt| of the bend at ``t`` [m/rad]."""
    return _speed_from(l_, h, k, span_1, span_2, t, math.cos(t), math.sin(t))


@kernel
def _speed_from(l_, h, k, span_1, span_2, t, cos_t, sin_t):
    """Return :func:`_speed_at` at ``t`` from its cosine and sine."""
    _, _, x1, y1, _, _, _, _ = _bend_from(l_, h, k, span_1, span_2, t, cos_t, sin_t)
    return math.sqrt(x1 * x1 + y1 * y1)


@kernel
def _curvature_at(l_, h, k, span_1, span_2, t):
    """
    Return the curvature kappa [1/m] and dkappa/ds [1/m**2] of the bend at ``t``.

    kappa = (x' y'' - y' x'') / |P'|**3 (positive: the arc bends towards the
    centre), s growing from T1 (ds/dt = -|P'|).
    """
    _, _, x1, y1, x2, y2, x3, y3 = _bend_at(l_, h, k, span_1, span_2, t)
    kappa, rate, _ = _curvature_of(x1, y1, x2, y2, x3, y3)
    return kappa, rate


@kernel
def _curvature_of(x1, y1, x2, y2, x3, y3):
    """Return kappa [1/m], dkappa/ds [1/m**2] and |dQ/dt| [m/rad] from the t-derivatives."""
    speed = math.sqrt(x1 * x1 + y1 * y1)
    # One division: products with 1 / sigma (rounding apart, the same quotients).
    inverse = 1.0 / speed
    inverse_3 = inverse * inverse * inverse
    cross = x1 * y2 - y1 * x2
    cross_t = x1 * y3 - y1 * x3
    sigma_t = (x1 * x2 + y1 * y2) * inverse
    kappa = cross * inverse_3
    kappa_t = (cross_t - 3.0 * cross * sigma_t * inverse) * inverse_3
    return kappa, -kappa_t * inverse, speed


@kernel
def _bend_rows(bend, t, out):
    """Fill ``out`` (8, N) with x, y and their first three derivatives by t at ``t`` (N,)."""
    l_, h, k, span_1, span_2 = bend
    for row in range(t.size):
        values = _bend_at(l_, h, k, span_1, span_2, t[row])
        for index in range(8):
            out[index, row] = values[index]


@kernel
def _offset_rows(bend, t, out):
    """Fill ``out`` (4, N) with :func:`_offset_at` at ``t`` (N,)."""
    l_, _, _, span_1, span_2 = bend
    for row in range(t.size):
        values = _offset_at(l_, span_1, span_2, t[row])
        for index in range(4):
            out[index, row] = values[index]


@kernel
def _speed_rows(bend, t, out):
    """Fill ``out`` (N,) with the bend's speed |dQ/dt| at ``t`` (N,)."""
    l_, h, k, span_1, span_2 = bend
    for row in range(t.size):
        out[row] = _speed_at(l_, h, k, span_1, span_2, t[row])


@kernel
def _curvature_rows(bend, t, kappa, rate):
    """Fill ``kappa`` and ``rate`` (N,) with :func:`_curvature_at` at ``t`` (N,)."""
    l_, h, k, span_1, span_2 = bend
    for row in range(t.size):
        kappa[row], rate[row] = _curvature_at(l_, h, k, span_1, span_2, t[row])


@kernel
def _grid_rows(bend, grid, kappa, rate, speed):
    """
    Fill ``kappa``, ``rate`` and ``speed`` (N,) at t (N,): one evaluation of the bend.

    ``grid`` (3, N) holds t and its cosine and sine (:func:`_trig_table`).
    """
    l_, h, k, span_1, span_2 = bend
    for row in range(grid.shape[1]):
        _, _, x1, y1, x2, y2, x3, y3 = _bend_from(l_, h, k, span_1, span_2, grid[0, row],
                                                  grid[1, row], grid[2, row])
        kappa[row], rate[row], speed[row] = _curvature_of(x1, y1, x2, y2, x3, y3)


@kernel
def _trig_rows(t, out):
    """Fill ``out`` (3, N) with ``t`` (N,), its cosine and its sine (as the kernels take them)."""
    for row in range(t.size):
        out[0, row], out[1, row], out[2, row] = t[row], math.cos(t[row]), math.sin(t[row])


def _trig_table(t):
    """Return t (N,), its cosine and its sine as rows (3, N) (:func:`_trig_rows`)."""
    table = np.empty((3, t.size))
    _trig_rows(np.array(t, dtype=float), table)
    return table


@kernel
def _integral_at(l_, h, k, span_1, span_2, t_start, t_end, nodes, weights):
    """Return the arc length between ``t_start`` and ``t_end`` (Gauss-Legendre), >= 0."""
    half = 0.5 * (t_end - t_start)
    middle = 0.5 * (t_end + t_start)
    total = 0.0
    for node in range(nodes.size):
        total += _speed_at(l_, h, k, span_1, span_2, middle + half * nodes[node]) * weights[node]
    return abs(half) * total


@kernel
def _panel_integral(l_, h, k, span_1, span_2, panels, panel, weights):
    """
    Return :func:`_integral_at` over panel ``panel`` of ``panels`` (:func:`_panel_nodes`).

    Its nodes, their cosines and sines and its half width, as :func:`_integral_at` computes
    them, come from the table.
    """
    total = 0.0
    for node in range(weights.size):
        total += _speed_from(l_, h, k, span_1, span_2, panels[panel, 0, node],
                             panels[panel, 1, node], panels[panel, 2, node]) * weights[node]
    return panels[panel, 3, 0] * total


@kernel
def _panel_nodes(panel_t, nodes, out):
    """
    Fill ``out`` (N - 1, 4, n) with the nodes of each panel of ``panel_t`` (N,).

    Rows 0-2 of a panel: its Gauss-Legendre nodes t (``nodes``, (n,), as
    :func:`_integral_at` places them), their cosine and sine; row 3: its half width |h|.
    """
    for panel in range(panel_t.size - 1):
        t_start, t_end = panel_t[panel], panel_t[panel + 1]
        half = 0.5 * (t_end - t_start)
        middle = 0.5 * (t_end + t_start)
        for node in range(nodes.size):
            t = middle + half * nodes[node]
            out[panel, 0, node], out[panel, 1, node], out[panel, 2, node] = (
                t, math.cos(t), math.sin(t))
            out[panel, 3, node] = abs(half)


@kernel
def _s_from_t_rows(bend, panel_t, panel_s, t, nodes, weights, out):
    """Fill ``out`` (N,) with the arc length from T1 at ``t`` (N,): table plus one panel's."""
    l_, h, k, span_1, span_2 = bend
    # Panel i spans panel_t[i] >= t >= panel_t[i + 1] (panel_t falls).
    rising = panel_t[::-1]
    count = panel_t.size - 1
    for row in range(t.size):
        here = min(max(t[row], 0.0), math.pi)
        panel = min(max(count - np.searchsorted(rising, here, side='left'), 0), count - 1)
        out[row] = panel_s[panel] + _integral_at(l_, h, k, span_1, span_2, panel_t[panel],
                                                 here, nodes, weights)


@kernel
def _table_rows(bend, panel_t, nodes, weights, grid, grid_panels, panel_s, quintics):
    """
    Fill the arc-length table at the panel bounds ``panel_t`` (N,), falling from pi to 0.

    ``panel_s`` gets the arc length from T1 (Gauss-Legendre on each panel); row i of
    ``quintics`` (N - 1, 7) the coefficients of t(s) on panel i in x = (s - s_i) / width
    (x**0 to x**5) and 1 / width: the quintic through t, dt/ds and d2t/ds2 at both ends,
    with ds/dt = -sigma, so dt/ds = -1/sigma and d2t/ds2 = -sigma_t / sigma**3. Bounds and
    panels of the breakless grid (``grid``, (3, M): :func:`_trig_table`; its panels'
    nodes ``grid_panels``, :func:`_panel_nodes`) take their cosines and sines from there.
    """
    l_, h, k, span_1, span_2 = bend
    count = panel_t.size
    dt_ds, d2t_ds2 = np.empty(count), np.empty(count)
    # Each bound's index on the grid, or -1 (a break between grid points).
    on_grid = np.full(count, -1, np.int64)
    column = 0
    for row in range(count):
        while column < grid.shape[1] and grid[0, column] > panel_t[row]:
            column += 1
        if column < grid.shape[1] and grid[0, column] == panel_t[row]:
            on_grid[row] = column
            values = _bend_from(l_, h, k, span_1, span_2, panel_t[row], grid[1, column],
                                grid[2, column])
        else:
            values = _bend_at(l_, h, k, span_1, span_2, panel_t[row])
        _, _, x1, y1, x2, y2, _, _ = values
        sigma = math.sqrt(x1 * x1 + y1 * y1)
        sigma_t = (x1 * x2 + y1 * y2) / sigma
        dt_ds[row] = -1.0 / sigma
        d2t_ds2[row] = -sigma_t / (sigma * sigma * sigma)
    panel_s[0] = 0.0
    for row in range(count - 1):
        column = on_grid[row]
        if column >= 0 and on_grid[row + 1] == column + 1:
            length = _panel_integral(l_, h, k, span_1, span_2, grid_panels, column, weights)
        else:
            length = _integral_at(l_, h, k, span_1, span_2, panel_t[row], panel_t[row + 1],
                                  nodes, weights)
        panel_s[row + 1] = panel_s[row] + length
    for panel in range(count - 1):
        after = panel + 1
        width = max(panel_s[after] - panel_s[panel], 1e-300)
        t0, t1 = panel_t[panel], panel_t[after]
        v0, v1 = dt_ds[panel] * width, dt_ds[after] * width
        a0, a1 = d2t_ds2[panel] * width * width, d2t_ds2[after] * width * width
        # The quintic through (t0, v0, a0) at x = 0 and (t1, v1, a1) at x = 1.
        jump = t1 - t0
        quintics[panel, 0] = t0
        quintics[panel, 1] = v0
        quintics[panel, 2] = 0.5 * a0
        quintics[panel, 3] = 10.0 * jump - 6.0 * v0 - 4.0 * v1 - 1.5 * a0 + 0.5 * a1
        quintics[panel, 4] = -15.0 * jump + 8.0 * v0 + 7.0 * v1 + 1.5 * a0 - a1
        quintics[panel, 5] = 6.0 * jump - 3.0 * (v0 + v1) - 0.5 * (a0 - a1)
        quintics[panel, 6] = 1.0 / width


class _ParametricArc:
    """
    Arc-length bookkeeping of a plane curve P(t), t from pi (T1) to 0 (T2).

    Subclasses provide ``speed(t)``, ``derivatives(t)``, ``components(t)`` and ``_breaks()``
    (parameters where the curve's derivatives jump); this gives ``s_from_t``
    and ``t_from_s``. The table is built once per curve, when first needed
    (the curve is frozen): the arc length at the panel bounds by Gauss-Legendre
    quadrature, and there the first two derivatives of t(s), so that
    ``t_from_s`` is one quintic Hermite evaluation per query, with no
    quadrature and no iteration.
    """

    @functools.cached_property
    def _table(self):
        """
        Arc-length table (t, s, quintics) at the panel bounds, t from pi (s = 0) to 0.

        The quintics (:func:`_table_rows`) interpolate t(s) on each panel. Every break is a
        panel bound, so that no quadrature panel and no interpolation panel straddles one.
        """
        # A copy either way: the kernels take writable arrays (one compiled form).
        panel_t = _panel_grid().copy()
        if self._breaks():
            panel_t = np.ascontiguousarray(
                np.unique(np.concatenate((panel_t, self._breaks())))[::-1])
        panel_s = np.empty(panel_t.size)
        quintics = np.empty((panel_t.size - 1, 7))
        _table_rows(self._bend, panel_t, GAUSS_LEGENDRE_NODES, GAUSS_LEGENDRE_WEIGHTS,
                    *_panel_table(), panel_s, quintics)
        return panel_t, panel_s, quintics

    def _rows(self, rows, function, t):
        """Return ``function(self._bend, t, out)``'s ``out`` (rows, N) for ``t`` (any shape)."""
        t = np.asarray(t, dtype=float)
        out = np.empty((rows, t.size))
        function(self._bend, np.ascontiguousarray(t).reshape(-1), out)
        return out.reshape((rows,) + t.shape)

    def components(self, t):
        """Return the (x, y) pairs of the curve and its first three derivatives by t at ``t``."""
        x, y, x1, y1, x2, y2, x3, y3 = self._rows(8, _bend_rows, t)
        return (x, y), (x1, y1), (x2, y2), (x3, y3)

    def derivatives(self, t):
        """Return the curve and its first three derivatives by t, each (N, 2) [m, m/rad, ...]."""
        rows = self._rows(8, _bend_rows, np.atleast_1d(t))
        return tuple(np.stack((rows[2 * order], rows[2 * order + 1]), axis=-1)
                     for order in range(4))

    def point(self, t):
        """Return points of the curve, shape (N, 2) [m], for t of shape (N,) [rad]."""
        x, y = self._rows(8, _bend_rows, t)[:2]
        return np.stack((x, y), axis=-1)

    def derivative(self, t):
        """Return the first derivative by t, shape (N, 2) [m/rad]."""
        x1, y1 = self._rows(8, _bend_rows, t)[2:4]
        return np.stack((x1, y1), axis=-1)

    def speed(self, t):
        """Return |dP/dt| [m/rad], shape of ``t``."""
        t = np.asarray(t, dtype=float)
        out = np.empty(t.size)
        _speed_rows(self._bend, np.ascontiguousarray(t).reshape(-1), out)
        return out.reshape(t.shape)

    def s_from_t(self, t):
        """Return the arc length from T1 to P(t), shape of ``t`` [m]."""
        t = np.asarray(t, dtype=float)
        out = np.empty(t.size)
        panel_t, panel_s, _ = self._table
        _s_from_t_rows(self._bend, panel_t, panel_s, np.ascontiguousarray(t).reshape(-1),
                       GAUSS_LEGENDRE_NODES, GAUSS_LEGENDRE_WEIGHTS, out)
        return out[0] if t.ndim == 0 else out.reshape(t.shape)

    def t_from_s(self, s):
        """
        Return t at arc length ``s`` from T1, shape of ``s``.

        Quintic Hermite interpolation of t(s) on the table's panel (t, dt/ds
        and d2t/ds2 exact at both ends); on 256 panels it is within 1e-10 m of
        the exact inverse of the arc length even on needle-thin arcs.
        """
        s = np.asarray(s, dtype=float)
        t = np.empty(s.size)
        _t_from_s_rows(*self._table, np.ascontiguousarray(s).reshape(-1), t)
        return t[0] if s.ndim == 0 else t.reshape(s.shape)

    def curvature_and_rate(self, t):
        """
        Return the curvature kappa [1/m] and dkappa/ds [1/m**2] at ``t``, each (N,).

        kappa = (x' y'' - y' x'') / |P'|**3 (positive: the arc bends towards the
        centre), s growing from T1 (ds/dt = -|P'|).
        """
        t = np.ascontiguousarray(np.asarray(t, dtype=float)).reshape(-1)
        kappa, rate = np.empty(t.size), np.empty(t.size)
        _curvature_rows(self._bend, t, kappa, rate)
        return kappa, rate

    def curvature_on_grid(self, samples):
        """
        Return t at ``samples`` even steps from pi to 0, kappa, dkappa/ds and |dQ/dt| there.

        Each (N,); |dQ/dt| [m/rad] is the curve's speed (:meth:`speed`), from the same
        evaluation of the curve.

        The dense grid of ``_DENSE_SAMPLES`` is computed once per arc and shared
        (its tightest point and the time-optimal scan's table both use it); the
        arrays are read-only.
        """
        if samples == _DENSE_SAMPLES:
            return self._dense_curvature
        return self._curvature_grid(samples)

    @functools.cached_property
    def _dense_curvature(self):
        """Return the curvature grid of ``_DENSE_SAMPLES``, computed once."""
        return self._curvature_grid(_DENSE_SAMPLES)

    def _curvature_grid(self, samples):
        """Return (t, kappa, dkappa/ds, |dQ/dt|) on ``samples`` even steps of t, read-only."""
        # A copy of the shared table: the kernels take writable arrays (one compiled form).
        table = _dense_table().copy() if samples == _DENSE_SAMPLES else _trig_table(
            np.linspace(math.pi, 0.0, samples))
        kappa, rate, speed = (np.empty(samples) for _ in range(3))
        _grid_rows(self._bend, table, kappa, rate, speed)
        grid = table[0], kappa, rate, speed
        for values in grid:
            values.setflags(write=False)
        return grid

    @property
    def length(self):
        """Arc length from T1 to T2 [m] (the table's total)."""
        return float(self._table[1][-1])


@dataclass(frozen=True, eq=False)
class EllipticArc(_ParametricArc):
    """
    Half ellipse from T1 = (-l, -h) over the top to T2 = (l, h), paper frame.

    Attributes
    ----------
    l : float
        Half the horizontal distance between the tangent points [m], > 0.
    h : float
        Half the rise from T1 to T2 [m], any sign.
    k : float
        Vertical conjugate semi-diameter [m], > 0 (the free parameter).
    a, b : float
        Semi-major and semi-minor axes [m] (derived).
    phi : float
        Angle of the major axis from the x axis [rad] (derived).
    theta_T1, theta_T2 : float
        Paper's ellipse parameter (eq. 29) at T1 and T2 [rad]; theta_T1 =
        theta_T2 + pi; along the motion theta decreases (derived).

    """

    l: float
    h: float
    k: float
    a: float = field(init=False)
    b: float = field(init=False)
    phi: float = field(init=False)
    theta_T1: float = field(init=False)
    theta_T2: float = field(init=False)

    def __post_init__(self):
        l_ = require_range('l', self.l, 0.0, low_open=True, unit='m')
        h = require_finite_h(self.h)
        k = require_range('k', self.k, 0.0, low_open=True, unit='m')
        total = l_ * l_ + h * h + k * k
        # Stable form of sqrt(total**2 - 4 l**2 k**2).
        spread = math.sqrt(((l_ - k) ** 2 + h * h) * ((l_ + k) ** 2 + h * h))
        a = math.sqrt(0.5 * (total + spread))
        b = l_ * k / a
        phi = 0.5 * math.atan2(2.0 * l_ * h, l_ * l_ - h * h - k * k)
        x1 = l_ * math.cos(phi) + h * math.sin(phi)
        y1 = -l_ * math.sin(phi) + h * math.cos(phi)
        theta_t2 = math.atan2(y1 / b, x1 / a)
        setattr_ = object.__setattr__
        for name, value in (('a', a), ('b', b), ('phi', phi), ('theta_T2', theta_t2),
                            ('theta_T1', theta_t2 + math.pi)):
            setattr_(self, name, value)

    def _breaks(self):
        """Return no breaks: the ellipse is smooth."""
        return ()

    @functools.cached_property
    def _bend(self):
        """Return (l, h, k, 0, 0): the ellipse as a bend without transitions (the kernels')."""
        return (float(self.l), float(self.h), float(self.k), 0.0, 0.0)

    @property
    def tightest_t(self):
        """Parameter t of the tightest point (the major-axis end on the arc) [rad]."""
        return float(self.t_from_theta(math.pi * math.ceil(self.theta_T2 / math.pi)))

    def t_from_theta(self, theta):
        """Return t = theta - theta_T2 [rad]."""
        return np.asarray(theta, dtype=float) - self.theta_T2

    def radius_of_curvature(self, theta):
        """Return rho(theta) = sigma**3 / (a b), the paper's eq. (34), shape of ``theta`` [m]."""
        return ellipse_speed(self.a, self.b, theta) ** 3 / (self.a * self.b)

    def sigma(self, theta):
        """Return sigma and its first two derivatives by theta (see :func:`ellipse_sigma`)."""
        return ellipse_sigma(self.a, self.b, theta)

    # -- lengths -------------------------------------------------------------------
    @property
    def length(self):
        """Exact arc length [m]: half the perimeter, 2 a E(1 - b**2/a**2)."""
        return 2.0 * self.a * elliptic_e(1.0 - (self.b / self.a) ** 2)

    @property
    def length_approx(self):
        """Paper's approximate arc length, eq. (27) [m]."""
        a, b = self.a, self.b
        return 0.5 * (math.pi * (a + b) / 2.0 + math.pi / math.sqrt(2.0) * math.hypot(a, b))

    # -- landmarks -----------------------------------------------------------------
    @property
    def apex(self):
        """Return the highest point (x, y) of the arc [m], as a (2,) array."""
        t_apex = math.atan2(self.k, self.h)
        return np.array([self.l * math.cos(t_apex), math.hypot(self.h, self.k)])

    @property
    def apex_height(self):
        """Apex height above the lower tangent point [m] (the paper's reported H*)."""
        return math.hypot(self.h, self.k) + abs(self.h)

    @property
    def min_radius(self):
        """Smallest radius of curvature on the arc, b**2 / a [m]."""
        return self.b * self.b / self.a

    @property
    def end_radius(self):
        """Radius of curvature at T1 and T2, k**2 / l [m]."""
        return self.k * self.k / self.l


@dataclass(frozen=True, eq=False)
class BlendedArc(_ParametricArc):
    """
    The ellipse with curvature-continuous (G2) transitions at T1 and T2, paper frame.

    Q(t) = P(t) + (delta(t), 0): the ellipse bent horizontally near its ends.
    Near T1 (u = (pi - t) / span_1 < 1) delta = -l span_1**2 f(u), near T2
    (u = t / span_2 < 1) delta = +l span_2**2 f(u), elsewhere 0, with the
    polynomial f(u) = u**2 (1 - u)**4 / 2 (:func:`_blend_shape`).
    Since d2P/dt2 = -P,
    x'' = -l cos t + delta'' is 0 at T1 and T2: the curvature starts and ends at
    0 (the vertical line's), the tangent stays vertical there, and at u = 1 the
    bent curve meets the ellipse with equal position, tangent and curvature
    (delta, delta', delta'' all vanish). Why this transition and not a
    clothoid: it is closed-form in the ellipse's own parameter (exact
    derivatives to the third, hence exact curvature and dkappa/ds for the
    timing, no Fresnel integrals), it needs no shift of the ellipse (the
    vertical lines and the ellipse beyond the transition stay the paper's),
    heights are untouched (delta is horizontal, so the apex height is the
    paper's), and the horizontal offset is bounded in closed form:
    |delta| <= l span**2 max f = l span**2 * 8/729 (:func:`blend_arc` sizes
    the spans by the distance from the ellipse, which is smaller). The price:
    any transition that starts on the vertical line and ends on the ellipse
    must turn as much as the ellipse does over the same stretch, so its
    curvature overshoots the ellipse's, and it leaves T1 and T2 with dkappa/ds
    about 12 kappa_T / (transition length), which caps the speed there by the
    normal jerk (a gentler start needs a larger overshoot further in, which
    the timing pays for dearly: see :func:`_blend_shape`).

    Attributes
    ----------
    ellipse : EllipticArc
        The paper's ellipse.
    span_1, span_2 : float
        Parameter widths [rad] of the transitions at T1 and T2, in
        (0, 0.45 pi].

    """

    ellipse: EllipticArc
    span_1: float
    span_2: float

    def __post_init__(self):
        if not isinstance(self.ellipse, EllipticArc):
            raise InvalidInputError(
                f'ellipse: expected an EllipticArc, got {type(self.ellipse).__name__}')
        for name in ('span_1', 'span_2'):
            require_range(name, getattr(self, name), 0.0, _BLEND_MAX_SPAN, low_open=True,
                          unit='rad')

    def _breaks(self):
        """Return where the transitions meet the ellipse (the third derivative jumps)."""
        return (math.pi - self.span_1, self.span_2)

    @functools.cached_property
    def _bend(self):
        """Return (l, h, k, span_1, span_2): the bend as the kernels take it."""
        ellipse = self.ellipse
        return (float(ellipse.l), float(ellipse.h), float(ellipse.k), float(self.span_1),
                float(self.span_2))

    def offset(self, t):
        """Return delta and its first three derivatives by t, each of the shape of ``t``."""
        return self._rows(4, _offset_rows, t)

    @functools.cached_property
    def _tightest(self):
        """(t, kappa) of the largest curvature on a dense grid, computed once."""
        t, kappa = self.curvature_on_grid(_DENSE_SAMPLES)[:2]
        index = int(np.argmax(kappa))
        return float(t[index]), float(kappa[index])

    @property
    def min_radius(self):
        """Smallest radius of curvature on the bent arc [m] (dense sampling)."""
        return 1.0 / self._tightest[1]

    @property
    def tightest_t(self):
        """Parameter t of the largest curvature (dense sampling) [rad]."""
        return self._tightest[0]

    @property
    def end_radius(self):
        """Radius of curvature at T1 and T2: infinite (the curvature is 0 there)."""
        return math.inf


def blend_arc(ellipse, tolerance=DEFAULT_JOIN_TOLERANCE):
    """
    Return the :class:`BlendedArc` of ``ellipse`` that deviates at most ``tolerance``.

    Each transition is as long as the tolerance allows (a longer one raises the
    curvature more gently, which lets the motion through it faster), measured
    as the distance from the ellipse (:func:`_transition_distance`), not the
    horizontal offset, which overstates it where the ellipse leans; but it ends
    before ``_BLEND_APEX_SHARE`` of the way to the apex and within
    ``_BLEND_MAX_SPAN``. Spans are halved while the bent curve would slow its
    parameter speed to below ``_BLEND_MIN_SPEED_SHARE`` of the ellipse's. A span
    whose transition would bend the other way for a while (tight, lopsided arcs)
    is shortened until its curvature keeps its sign (:func:`_one_way_span`).
    """
    tolerance = validate('join_tolerance', tolerance)
    # The horizontal offset bounds the distance: a span that is always short enough.
    safe = math.sqrt(tolerance / (_BLEND_PEAK * ellipse.l))
    t_apex = math.atan2(ellipse.k, ellipse.h)
    span_1, span_2 = (
        _longest_span(ellipse, tolerance, safe, min(_BLEND_APEX_SHARE * share, _BLEND_MAX_SPAN),
                      at_t1)
        for share, at_t1 in ((math.pi - t_apex, True), (t_apex, False)))
    span_1 = _one_way_span(ellipse, span_1, True)
    span_2 = _one_way_span(ellipse, span_2, False)
    t = _dense_grid()
    least = _BLEND_MIN_SPEED_SHARE * _ellipse_slowest(ellipse._bend, t)
    for _ in range(20):
        bent = BlendedArc(ellipse, span_1, span_2)
        if _keeps_speed(bent._bend, ellipse.b, least, t):
            return bent
        span_1, span_2 = 0.5 * span_1, 0.5 * span_2
    raise DegenerateGeometryError(
        f'join: expected a regular G2 transition for l = {ellipse.l:.6g} m, '
        f'h = {ellipse.h:.6g} m, got none; use join paper')


def _one_way_span(ellipse, span, at_t1):
    """
    Return the longest span up to ``span`` whose transition never bends the other way.

    The transition subtracts a fixed share of the ellipse's own horizontal
    acceleration; on a long span of a tight, lopsided ellipse that overturns the
    curvature for a while. The sign is checked on ``_BLEND_SIGN_SAMPLES`` of the
    transition; a span that fails is halved until one passes, then bisected
    between the two (a shorter span moves the curve less from the ellipse, so it
    stays within the tolerance).
    """
    if _bends_one_way(ellipse._bend, span, at_t1, _sign_grid()):
        return span
    low, high = span, span
    for _ in range(_BLEND_SIGN_HALVINGS):
        high, low = low, 0.5 * low
        if _bends_one_way(ellipse._bend, low, at_t1, _sign_grid()):
            break
    else:
        raise DegenerateGeometryError(
            f'join: expected a G2 transition that bends one way for l = {ellipse.l:.6g} m, '
            f'h = {ellipse.h:.6g} m, got none; use join paper')
    for _ in range(_BLEND_SIGN_BISECTIONS):
        middle = 0.5 * (low + high)
        if _bends_one_way(ellipse._bend, middle, at_t1, _sign_grid()):
            low = middle
        else:
            high = middle
    return low


def _longest_span(ellipse, tolerance, safe, cap, at_t1):
    """
    Return the longest span up to ``cap`` found within ``tolerance`` (``safe`` at least).

    The distance grows about as the span squared (the offset does exactly):
    each step rescales the span by the square root of the room left, and the
    longest span whose distance was checked within the limit is kept.
    """
    # Sampled: keep a share of the tolerance for what falls between the samples.
    limit = (1.0 - _BLEND_DISTANCE_MARGIN) * tolerance
    best = span = min(safe, cap)
    for _ in range(_BLEND_SPAN_STEPS):
        distance = _transition_distance(ellipse._bend, span, at_t1, *_distance_grid(),
                                        _BLEND_FOOT_STEPS)
        if distance <= limit:
            best = max(best, span)
        following = min(span * math.sqrt(limit / distance), cap)
        if abs(following - span) <= _BLEND_SPAN_PRECISION * span:
            break
        span = following
    return best


@kernel
def _transition_distance(ellipse, span, at_t1, u, shape, order, foot_steps):
    """
    Return an upper bound on the distance of a transition from the ellipse [m].

    ``ellipse`` is (l, h, k, 0, 0); ``u`` and ``shape`` are the transition's samples and
    f(u) there, ``order`` their indices by falling f (:func:`_distance_grid`). Per sample
    the smaller of the horizontal offset and the distance to the ellipse point that
    ``foot_steps`` Newton steps on (P(t) - Q) . P'(t) = 0 reach from the sample's own
    parameter (either is a point of the paper's path).
    """
    l_, h, k, _, _ = ellipse
    scale = l_ * span * span
    largest = 0.0
    # Samples by falling offset: a sample counts at most its offset, so once that is no more
    # than the largest distance found, neither it nor any after it can raise the bound.
    for row in order:
        offset = scale * shape[row]
        if offset <= largest:
            break
        t = math.pi - span * u[row] if at_t1 else span * u[row]
        x, y, slope_x, slope_y = _ellipse_at(l_, h, k, t)
        bent_x = x - offset if at_t1 else x + offset
        bent_y = y
        foot = t
        for step in range(foot_steps):
            if step:
                x, y, slope_x, slope_y = _ellipse_at(l_, h, k, foot)
            gap_x, gap_y = x - bent_x, y - bent_y
            # d/dt of gap . P' is |P'|**2 + gap . P'' with P'' = -P.
            rate = (slope_x * slope_x + slope_y * slope_y) - (gap_x * x + gap_y * y)
            foot = min(math.pi, max(0.0, foot - (gap_x * slope_x + gap_y * slope_y) / rate))
        x, y, _, _ = _ellipse_at(l_, h, k, foot)
        distance = math.sqrt((x - bent_x) ** 2 + (y - bent_y) ** 2)
        largest = max(largest, min(distance, offset))
    return largest


@functools.cache
def _distance_grid():
    """Return the transition samples u, f(u) there and u's order by falling f (read-only)."""
    u = np.linspace(0.0, 1.0, _BLEND_DISTANCE_SAMPLES)
    shape = np.array([_blend_shape(value)[0] for value in u])
    order = np.argsort(-shape, kind='stable')
    for values in (u, shape, order):
        values.setflags(write=False)
    return u, shape, order


@functools.cache
def _panel_grid():
    """Return the panel bounds of the arc-length table without breaks (read-only)."""
    t = np.linspace(math.pi, 0.0, _N_PANELS + 1)
    t.setflags(write=False)
    return t


@functools.cache
def _sign_grid():
    """Return the transition samples u of the sign check, computed once (read-only)."""
    # Its start (u = 0) has curvature 0, up to rounding: only the samples after it count.
    u = np.linspace(0.0, 1.0, _BLEND_SIGN_SAMPLES)[1:]
    u.setflags(write=False)
    return u


@functools.cache
def _dense_grid():
    """Return ``_DENSE_SAMPLES`` even steps of t from pi to 0, computed once (read-only)."""
    t = np.linspace(math.pi, 0.0, _DENSE_SAMPLES)
    t.setflags(write=False)
    return t


@functools.cache
def _dense_table():
    """Return :func:`_trig_table` of :func:`_dense_grid`, computed once (read-only)."""
    table = _trig_table(_dense_grid())
    table.setflags(write=False)
    return table


@functools.cache
def _panel_table():
    """
    Return the breakless panel grid's :func:`_trig_table` and :func:`_panel_nodes` (read-only).

    Every curve's arc-length table has these bounds and panels, and only its breaks besides.
    """
    grid = _trig_table(_panel_grid())
    panels = np.empty((_N_PANELS, 4, GAUSS_LEGENDRE_NODES.size))
    _panel_nodes(grid[0].copy(), GAUSS_LEGENDRE_NODES, panels)
    for values in (grid, panels):
        values.setflags(write=False)
    return grid, panels


@kernel
def _bends_one_way(ellipse, span, at_t1, u):
    """Return whether the transition of ``span`` at T1 (``at_t1``) or T2 has curvature >= 0."""
    l_, h, k, _, _ = ellipse
    # Both spans alike: the two transitions never overlap (each is within _BLEND_MAX_SPAN).
    for row in range(u.size):
        t = math.pi - span * u[row] if at_t1 else span * u[row]
        kappa, _ = _curvature_at(l_, h, k, span, span, t)
        if not kappa >= 0.0:
            return False
    return True


@kernel
def _ellipse_slowest(ellipse, t):
    """
    Return the smallest speed |dP/dt| of the ellipse (l, h, k, 0, 0) on the even grid ``t``.

    ``t`` falls from pi to 0. |dP/dt|**2 is a constant plus a sinusoid in 2 t: along the
    grid, taken round (pi and 0 are the same point of it), it falls towards its minimum at
    t* and rises beyond, so the grid's smallest value is at a sample next to t* (or next to
    pi or 0 when t* is near them): those few samples are evaluated.
    """
    l_, h, k, _, _ = ellipse
    # |dP/dt|**2 = const + R cos(2 t - psi) with R cos psi = (k**2 - l**2 - h**2) / 2 and
    # R sin psi = -h k: the minimum is at 2 t* = psi + pi.
    psi = math.atan2(-h * k, 0.5 * (k * k - l_ * l_ - h * h))
    lowest = (0.5 * (psi + math.pi)) % math.pi
    last = t.size - 1
    nearest = int(round((math.pi - lowest) / math.pi * last))
    slowest = math.inf
    for centre in (0, nearest, last):
        for row in range(max(centre - 4, 0), min(centre + 5, t.size)):
            slowest = min(slowest, _speed_at(l_, h, k, 0.0, 0.0, t[row]))
    return slowest


@kernel
def _keeps_speed(bend, semi_minor, least, t):
    """
    Return whether the bend's speed |dQ/dt| is at least ``least`` on the samples ``t`` (N,).

    Outside the transitions the bend is the ellipse (``least`` is below its slowest): only the
    samples inside them are checked, and none when a bound says so: |dQ/dt| >= |dP/dt| -
    |delta'| >= b - l span max|f'|.
    """
    l_, h, k, span_1, span_2 = bend
    slope = _BLEND_SLOPE_BOUND * l_ * max(span_1, span_2)
    if (1.0 - 1e-12) * semi_minor - slope >= least:
        return True
    for row in range(t.size):
        if (math.pi - t[row]) / span_1 < 1.0 or t[row] / span_2 < 1.0:
            if not _speed_at(l_, h, k, span_1, span_2, t[row]) >= least:
                return False
    return True


def require_finite_h(h):
    """Return the half rise as float; any finite value is allowed."""
    return require_range('h', h)


def arc_for_policy(half_width, h, policy):
    """Return the EllipticArc that ``policy`` chooses for half-width l and half-rise h."""
    if policy.kind == 'paper':
        k = conjugate_k_from_phi(half_width, h, paper_phi(half_width, h))
    elif policy.kind == 'apex_clearance':
        clearance = policy.apex_clearance
        k = math.sqrt(clearance * clearance + 2.0 * clearance * abs(h))
    else:
        k = _k_for_min_radius(half_width, h, policy.min_radius)
    return EllipticArc(half_width, h, k)


def _min_radius_of(half_width, h, k):
    """Return b**2 / a for the tangent ellipses of conjugate semi-diameters k (array)."""
    total = half_width * half_width + h * h + k * k
    spread = np.sqrt(((half_width - k) ** 2 + h * h) * ((half_width + k) ** 2 + h * h))
    a_squared = 0.5 * (total + spread)
    return (half_width * k) ** 2 / a_squared ** 1.5


def _k_for_min_radius(half_width, h, min_radius):
    """
    Return the smallest k whose arc has min radius >= ``min_radius`` (shortest such arc).

    The arc length grows with k (the arcs are nested), and b**2/a first grows
    then falls with k, so the answer is on the rising branch.
    """
    scale = math.hypot(half_width, h)
    grid = np.geomspace(1e-6 * scale, 50.0 * scale, 400)
    radii = _min_radius_of(half_width, h, grid)
    best = int(np.argmax(radii))
    if radii[best] < min_radius:
        raise DegenerateGeometryError(
            f'min_radius: expected at most {radii[best]:.6g} m (the largest smallest-radius '
            f'any tangent ellipse reaches for l = {half_width:.6g} m, h = {h:.6g} m), '
            f'got {min_radius:.6g} m')
    first = int(np.argmax(radii >= min_radius))
    if first == 0:
        return float(grid[0])
    low, high = grid[first - 1], grid[first]
    for _ in range(60):
        middle = 0.5 * (low + high)
        if _min_radius_of(half_width, h, middle) >= min_radius:
            high = middle
        else:
            low = middle
    return float(high)


@dataclass(frozen=True)
class PathSamples:
    """
    Samples of the composite path by arc length s; every array has shape (N, 3).

    Attributes
    ----------
    position : numpy.ndarray
        TCP position in the base frame [m].
    tangent : numpy.ndarray
        Unit tangent dp/ds.
    curvature : numpy.ndarray
        d2p/ds2 [1/m], the curvature vector (its norm is the curvature).
    curvature_rate : numpy.ndarray
        d3p/ds3 [1/m**2].

    """

    position: np.ndarray
    tangent: np.ndarray
    curvature: np.ndarray
    curvature_rate: np.ndarray


@dataclass(frozen=True, eq=False)
class PickPlacePath:
    """
    The composite path: lift P1 -> T1, arc T1 -> T2, descent T2 -> P2 (base frame, m).

    Build it with :func:`plan_path`. A straight move (pick and place less than
    1 mm apart horizontally) has no arc: one straight
    segment from P1 to P2, stored as the lift when it rises (or stays level)
    and as the descent when it goes down.

    Attributes
    ----------
    pick, place : numpy.ndarray
        P1 and P2, shape (3,).
    tangent_1, tangent_2 : numpy.ndarray
        T1 and T2, shape (3,).
    arc : EllipticArc or None
        The arc in the paper frame; None for a pure vertical move.
    direction : numpy.ndarray
        Horizontal unit vector u from P1 towards P2, shape (3,) (zero for a
        vertical move).
    segment_lengths : numpy.ndarray
        Lengths of (lift, bend, descent) [m], shape (3,).
    bend : EllipticArc or BlendedArc or None
        The curve followed from T1 to T2: the arc itself (``join`` 'paper') or
        the arc with G2 transitions (``join`` 'g2'); None without an arc.
    join : str
        One of ``JOINS``.

    """

    pick: np.ndarray
    place: np.ndarray
    tangent_1: np.ndarray
    tangent_2: np.ndarray
    arc: EllipticArc | None
    direction: np.ndarray
    segment_lengths: np.ndarray
    bend: EllipticArc | BlendedArc | None = None
    join: str = 'paper'

    def __post_init__(self):
        if self.join not in JOINS:
            raise InvalidInputError(
                f'join: expected one of {", ".join(JOINS)}, got {self.join!r}')
        if self.bend is None:
            object.__setattr__(self, 'bend', self.arc)

    @functools.cached_property
    def segment_ends(self):
        """Arc length at P1, T1, T2, P2 [m], shape (4,) (read-only)."""
        ends = np.concatenate(([0.0], np.cumsum(self.segment_lengths)))
        ends.flags.writeable = False
        return ends

    @functools.cached_property
    def length(self):
        """Total path length [m]."""
        return float(np.sum(self.segment_lengths))

    @functools.cached_property
    def midpoint(self):
        """Origin of the paper frame in the base frame, shape (3,)."""
        return 0.5 * (self.tangent_1 + self.tangent_2)

    def to_base(self, points):
        """Map paper-frame points (N, 2) to base-frame points (N, 3)."""
        points = np.asarray(points, dtype=float)
        vertical = np.array([0.0, 0.0, 1.0])
        return (self.midpoint + points[..., :1] * self.direction
                + points[..., 1:2] * vertical)

    @property
    def apex(self):
        """Highest point of the arc in the base frame, shape (3,) (the higher end if no arc)."""
        if self.arc is None:
            return self.pick if self.pick[2] >= self.place[2] else self.place
        return self.to_base(self.arc.apex)

    def at_lengths(self, s):
        """
        Sample the path at arc lengths ``s`` (N,) [m], clipped to [0, length].

        Returns
        -------
        PathSamples
            Position, unit tangent and the second and third derivatives by s.

        """
        return PathSamples(*(np.ascontiguousarray(rows.T) for rows in self.rows_at_lengths(s)))

    def rows_at_lengths(self, s):
        """
        Return :meth:`at_lengths` with each array as rows (3, N), one per coordinate.

        Products with per-sample factors (N,) then run along the samples: on
        (N, 3) arrays times (N, 1) factors NumPy's innermost loop runs over 3
        coordinates, several times slower.

        Returns
        -------
        tuple of numpy.ndarray
            Position, unit tangent, curvature vector d2p/ds2 and d3p/ds3, each (3, N).

        """
        s = np.atleast_1d(np.asarray(s, dtype=float))
        count = s.shape[0]
        if self.arc is None:
            s = np.clip(s, 0.0, self.length)
            line = ((self.place - self.pick) / self.length)[:, None]
            return (self.pick[:, None] + line * s, np.repeat(line, count, axis=1),
                    np.zeros((3, count)), np.zeros((3, count)))
        rows = np.empty((4, 3, count))
        _path_rows(np.ascontiguousarray(s), self._frame, *self.bend._table, rows)
        return tuple(rows)

    @functools.cached_property
    def _frame(self):
        """
        Return the path as :func:`_path_rows` takes it, shape (22,).

        Arc length at T1, at T2, the lift's, the descent's and the path's; P1, T2, the
        direction u and the paper frame's origin (3 each); the bend's (l, h, k, span_1, span_2).
        """
        _, s_t1, s_t2, _ = self.segment_ends
        return np.concatenate((
            [s_t1, s_t2, self.segment_lengths[0], self.segment_lengths[2], self.length],
            self.pick, self.tangent_2, self.direction, self.midpoint, self.bend._bend))


@kernel
def _panel_of(panel_s, s, guess):
    """
    Return the panel of arc length ``s``: the last i <= N - 2 with panel_s[i] <= s (s >= 0).

    Samples come sorted, mostly: the search starts from ``guess`` (the previous sample's
    panel) and steps to a neighbour, and bisects only when ``s`` is further away.
    """
    last = panel_s.size - 2
    panel = min(max(guess, 0), last)
    if panel_s[panel] <= s:
        if panel == last or s < panel_s[panel + 1]:
            return panel
        if panel + 1 == last or s < panel_s[panel + 2]:
            return panel + 1
    return min(max(np.searchsorted(panel_s, s, side='right') - 1, 0), last)


@kernel
def _t_at(panel_t, panel_s, quintics, s, guess):
    """Return :meth:`_ParametricArc.t_from_s` of one arc length ``s`` [m], and its panel."""
    s = min(max(s, 0.0), panel_s[-1])
    panel = _panel_of(panel_s, s, guess)
    # Element by element: a row view would cost a reference count per sample.
    x = (s - panel_s[panel]) * quintics[panel, 6]
    value = quintics[panel, 0] + x * (quintics[panel, 1] + x * (quintics[panel, 2] + x * (
        quintics[panel, 3] + x * (quintics[panel, 4] + x * quintics[panel, 5]))))
    return min(max(value, panel_t[panel + 1]), panel_t[panel]), panel


@kernel
def _t_from_s_rows(panel_t, panel_s, quintics, lengths, out):
    """Fill ``out`` (N,) with :meth:`_ParametricArc.t_from_s` of ``lengths`` (N,)."""
    panel = 0
    for row in range(lengths.size):
        out[row], panel = _t_at(panel_t, panel_s, quintics, lengths[row], panel)


@kernel
def _path_rows(s, frame, panel_t, panel_s, quintics, rows):
    """
    Fill ``rows`` (4, 3, N) with :meth:`PickPlacePath.rows_at_lengths` at arc lengths ``s`` (N,).

    ``frame`` is :attr:`PickPlacePath._frame`. On the bend, with g = ds/dt = -sigma,
    sigma = |dP/dt| and P_n the n-th derivative by t: r_s = P_1 / g,
    r_ss = (P_2 - g' r_s) / g**2 and r_sss = (P_3 - g'' r_s - 3 g g' r_ss) / g**3.
    """
    s_t1, s_t2, lift, descent, length = frame[0], frame[1], frame[2], frame[3], frame[4]
    l_, h, k, span_1, span_2 = frame[17], frame[18], frame[19], frame[20], frame[21]
    # Base-frame components: P1 (5-7), T2 (8-10), the direction u (11-13), the origin (14-16).
    panel = 0
    for column in range(s.size):
        here = min(max(s[column], 0.0), length)
        for order in range(1, 4):
            for axis in range(3):
                rows[order, axis, column] = 0.0
        if here <= s_t1 and lift > 0.0:
            rows[0, 0, column] = frame[5]
            rows[0, 1, column] = frame[6]
            rows[0, 2, column] = frame[7] + here
            rows[1, 2, column] = 1.0
            continue
        if here >= s_t2 and descent > 0.0:
            rows[0, 0, column] = frame[8]
            rows[0, 1, column] = frame[9]
            rows[0, 2, column] = frame[10] - (here - s_t2)
            rows[1, 2, column] = -1.0
            continue
        t, panel = _t_at(panel_t, panel_s, quintics, here - s_t1, panel)
        x, y, x1, y1, x2, y2, x3, y3 = _bend_at(l_, h, k, span_1, span_2, t)
        sigma = math.sqrt(x1 * x1 + y1 * y1)
        # One division: products with g_inv = -1 / sigma (rounding apart, the same quotients).
        g_inv = -1.0 / sigma
        sigma_1 = -(x1 * x2 + y1 * y2) * g_inv
        sigma_2 = -(x2 * x2 + y2 * y2 + x1 * x3 + y1 * y3 - sigma_1 * sigma_1) * g_inv
        g1, g2 = -sigma_1, -sigma_2
        tangent_x, tangent_y = x1 * g_inv, y1 * g_inv
        g_inv_2 = g_inv * g_inv
        curvature_x = (x2 - g1 * tangent_x) * g_inv_2
        curvature_y = (y2 - g1 * tangent_y) * g_inv_2
        three_g_g1 = -3.0 * sigma * g1
        g_inv_3 = g_inv_2 * g_inv
        rate_x = (x3 - g2 * tangent_x - three_g_g1 * curvature_x) * g_inv_3
        rate_y = (y3 - g2 * tangent_y - three_g_g1 * curvature_y) * g_inv_3
        # The base frame's x, y are along the paper frame's x; its z is the paper's y.
        for axis in range(2):
            direction = frame[11 + axis]
            rows[0, axis, column] = x * direction + frame[14 + axis]
            rows[1, axis, column] = tangent_x * direction
            rows[2, axis, column] = curvature_x * direction
            rows[3, axis, column] = rate_x * direction
        rows[0, 2, column] = x * frame[13] + y + frame[16]
        rows[1, 2, column] = tangent_x * frame[13] + tangent_y
        rows[2, 2, column] = curvature_x * frame[13] + curvature_y
        rows[3, 2, column] = rate_x * frame[13] + rate_y


def require_coordinates(name, point):
    """Return ``point`` as a (3,) array of finite coordinates within +-10 m."""
    point = require_point(name, point)
    if np.abs(point).max() > _MAX_COORDINATE:
        raise InvalidInputError(
            f'{name}: expected coordinates within +-{_MAX_COORDINATE:g} m, got {point.tolist()}')
    return point


def plan_path(pick, place, pick_clearance=default_of('pick_clearance'),
              place_clearance=default_of('place_clearance'), policy=None,
              join='paper', join_tolerance=DEFAULT_JOIN_TOLERANCE):
    """
    Build the composite path from pick P1 to place P2.

    Parameters
    ----------
    pick, place : array_like
        P1 and P2 in the base frame [m], shape (3,).
    pick_clearance, place_clearance : float
        Vertical segment lengths c1, c2 [m], in [0, 1].
    policy : ArcPolicy, optional
        How the ellipse is chosen; the paper's rule by default.
    join : str
        ``'paper'`` (default here: the paper's path, a curvature step at T1
        and T2) or ``'g2'`` (:class:`BlendedArc`; the planner's default).
    join_tolerance : float
        Largest distance of the ``'g2'`` path from the paper's [m], in (0, 0.01].

    Returns
    -------
    PickPlacePath

    Raises
    ------
    InvalidInputError
        Non-finite coordinates or clearances out of range.
    DegenerateGeometryError
        Pick and place coincide, or the arc policy admits no ellipse (or only a
        needle-thin one).

    """
    pick = require_coordinates('pick', pick)
    place = require_coordinates('place', place)
    c1 = validate('pick_clearance', pick_clearance)
    c2 = validate('place_clearance', place_clearance)
    policy = policy or ArcPolicy()
    if join not in JOINS:
        raise InvalidInputError(f'join: expected one of {", ".join(JOINS)}, got {join!r}')
    offset = place - pick
    horizontal = math.hypot(offset[0], offset[1])
    if np.linalg.norm(offset) < _MIN_MOVE_DISTANCE:
        raise DegenerateGeometryError(
            f'pick and place: expected points at least {_MIN_MOVE_DISTANCE:g} m apart, '
            f'got {np.linalg.norm(offset):.3g} m (pick {pick.tolist()}, place {place.tolist()})')
    if horizontal < _MIN_HORIZONTAL_DISTANCE:
        # One straight line: the object stays in the same column, no clearance to clear.
        distance = float(np.linalg.norm(offset))
        rises = offset[2] >= 0.0
        lengths = np.array([distance, 0.0, 0.0] if rises else [0.0, 0.0, distance])
        top = place if rises else pick
        return PickPlacePath(pick, place, top.copy(), top.copy(), None, np.zeros(3), lengths,
                             join=join)
    up = np.array([0.0, 0.0, 1.0])
    tangent_1 = pick + c1 * up
    tangent_2 = place + c2 * up
    direction = np.array([offset[0], offset[1], 0.0]) / horizontal
    arc = arc_for_policy(0.5 * horizontal, 0.5 * float(tangent_2[2] - tangent_1[2]), policy)
    if arc.min_radius < _MIN_ARC_RADIUS:
        raise DegenerateGeometryError(
            f'arc ({policy.kind}): expected a smallest radius of curvature of at least '
            f'{_MIN_ARC_RADIUS * 1e3:g} mm, got {arc.min_radius * 1e3:.3g} mm (a needle-thin '
            f'ellipse for l = {arc.l:.4g} m, h = {arc.h:.4g} m); use the min_radius arc policy '
            f'with a larger min_radius, or move pick and place further apart horizontally')
    bend = blend_arc(arc, join_tolerance) if join == 'g2' else arc
    lengths = np.array([c1, bend.length, c2])
    return PickPlacePath(pick, place, tangent_1, tangent_2, arc, direction, lengths, bend, join)
