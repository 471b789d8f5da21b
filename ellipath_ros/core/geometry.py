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
the first and last stretch of the ellipse horizontally by a quintic in its
parameter, so that the curvature rises continuously from 0 at T1 (falls to 0
at T2) and the path stays within ``join_tolerance`` of the paper's.
"""

from dataclasses import dataclass, field
import math

import numpy as np

from .errors import DegenerateGeometryError, InvalidInputError, require_point, require_range
from .settings import validate_fields

ARC_POLICIES = ('paper', 'apex_clearance', 'min_radius')
# How the vertical lines meet the arc: a curvature-continuous transition, or the paper's step.
JOINS = ('g2', 'paper')
DEFAULT_JOIN_TOLERANCE = 5e-4
# Largest value of the transition shape u**2 (1 - u)**3 / 2 on [0, 1] (at u = 2/5).
# Largest value of the transition shape u**2 (1 - u)**3 / 2 on [0, 1] (at u = 2/5).
_BLEND_PEAK = 54.0 / 3125.0
# A transition spans at most this share of the arc's parameter on its side of the apex...
_BLEND_APEX_SHARE = 0.8
# ... and at most this much of the parameter range [0, pi] (the two never overlap).
_BLEND_MAX_SPAN = 0.45 * math.pi
# The bent curve must keep at least this share of the ellipse's smallest parameter speed.
_BLEND_MIN_SPEED_SHARE = 0.2
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

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_N_PANELS = 256
# Newton steps after the Hermite guess: the guess is within ~1e-9 rad on 256 panels.
_NEWTON_STEPS = 2


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

    kind: str = 'paper'
    apex_clearance: float = 0.025
    min_radius: float = 0.02

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


class _ParametricArc:
    """
    Arc-length bookkeeping of a plane curve P(t), t from pi (T1) to 0 (T2).

    Subclasses provide ``speed(t)`` (= |dP/dt|) and call ``_build_length_table``
    in ``__post_init__``; this gives ``s_from_t`` and ``t_from_s``.
    """

    def _build_length_table(self, breaks=()):
        """
        Arc-length table: s at panel bounds, t running from pi (s = 0) to 0.

        ``breaks`` are parameters where the curve's derivatives jump (a panel
        bound each, so that no quadrature panel straddles one).
        """
        setattr_ = object.__setattr__
        panel_t = np.unique(np.concatenate((np.linspace(math.pi, 0.0, _N_PANELS + 1),
                                            breaks)))[::-1]
        setattr_(self, '_panel_t', panel_t)
        setattr_(self, '_panel_speed', self.speed(panel_t))
        setattr_(self, '_panel_s', np.concatenate(
            ([0.0], np.cumsum(self._integral(panel_t[:-1], panel_t[1:])))))

    def _integral(self, t_start, t_end):
        """Return the arc length between t_start and t_end (elementwise), >= 0."""
        t_start = np.asarray(t_start, dtype=float)
        t_end = np.asarray(t_end, dtype=float)
        half = 0.5 * (t_end - t_start)
        nodes = (0.5 * (t_end + t_start))[..., None] + half[..., None] * _GL_NODES
        return np.abs(half) * (self.speed(nodes) @ _GL_WEIGHTS)

    def s_from_t(self, t):
        """Return the arc length from T1 to P(t), shape of ``t`` [m]."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, math.pi)
        # Panel i spans panel_t[i] >= t >= panel_t[i + 1] (panel_t falls).
        count = self._panel_t.size - 1
        panel = np.clip(count - np.searchsorted(self._panel_t[::-1], t, side='left'), 0,
                        count - 1)
        return self._panel_s[panel] + self._integral(self._panel_t[panel], t)

    def t_from_s(self, s):
        """Return t at arc length ``s`` from T1 (Newton on the exact length), shape of s."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self._panel_s[-1])
        panel = np.clip(np.searchsorted(self._panel_s, s, side='right') - 1, 0,
                        self._panel_s.size - 2)
        t0, t1 = self._panel_t[panel], self._panel_t[panel + 1]
        s0, s1 = self._panel_s[panel], self._panel_s[panel + 1]
        # Cubic Hermite guess from the panel ends (dt/ds = -1/|P'|), then Newton steps.
        width = np.maximum(s1 - s0, 1e-300)
        x = (s - s0) / width
        slope0 = -width / self._panel_speed[panel]
        slope1 = -width / self._panel_speed[panel + 1]
        t = ((2 * x ** 3 - 3 * x ** 2 + 1) * t0 + (x ** 3 - 2 * x ** 2 + x) * slope0
             + (-2 * x ** 3 + 3 * x ** 2) * t1 + (x ** 3 - x ** 2) * slope1)
        t = np.clip(t, t1, t0)
        for _ in range(_NEWTON_STEPS):
            residual = s0 + self._integral(t0, t) - s
            t = np.clip(t + residual / np.maximum(self.speed(t), 1e-300), t1, t0)
        return t

    def curvature_and_rate(self, t):
        """
        Return the curvature kappa [1/m] and dkappa/ds [1/m**2] at ``t``, each (N,).

        kappa = (x' y'' - y' x'') / |P'|**3 (positive: the arc bends towards the
        centre), s growing from T1 (ds/dt = -|P'|).
        """
        _, d1, d2, d3 = self.derivatives(t)
        sigma = np.linalg.norm(d1, axis=-1)
        cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
        cross_t = d1[:, 0] * d3[:, 1] - d1[:, 1] * d3[:, 0]
        sigma_t = np.einsum('ij,ij->i', d1, d2) / sigma
        kappa = cross / sigma ** 3
        kappa_t = cross_t / sigma ** 3 - 3.0 * cross * sigma_t / sigma ** 4
        return kappa, -kappa_t / sigma

    @property
    def length(self):
        """Arc length from T1 to T2 [m] (the table's total)."""
        return float(self._panel_s[-1])


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
    _panel_t: np.ndarray = field(init=False, repr=False)
    _panel_s: np.ndarray = field(init=False, repr=False)
    _panel_speed: np.ndarray = field(init=False, repr=False)

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
        self._build_length_table()

    # -- parameterisation ------------------------------------------------------------
    def point(self, t):
        """Return points P(t), shape (N, 2) [m], for t of shape (N,) [rad]."""
        t = np.asarray(t, dtype=float)
        return np.stack((self.l * np.cos(t), self.h * np.cos(t) + self.k * np.sin(t)), axis=-1)

    def derivative(self, t):
        """Return dP/dt, shape (N, 2) [m/rad]; note d2P/dt2 = -P."""
        t = np.asarray(t, dtype=float)
        return np.stack((-self.l * np.sin(t), -self.h * np.sin(t) + self.k * np.cos(t)),
                        axis=-1)

    def speed(self, t):
        """Return |dP/dt|, shape (N,) [m/rad]."""
        sin_t, cos_t = np.sin(t), np.cos(t)
        return np.sqrt((self.l * sin_t) ** 2 + (self.k * cos_t - self.h * sin_t) ** 2)

    def derivatives(self, t):
        """Return P, dP/dt, d2P/dt2 = -P and d3P/dt3 = -dP/dt at ``t``, each (N, 2)."""
        p = self.point(t)
        d1 = self.derivative(t)
        return p, d1, -p, -d1

    @property
    def tightest_t(self):
        """Parameter t of the tightest point (the major-axis end on the arc) [rad]."""
        return float(self.t_from_theta(math.pi * math.ceil(self.theta_T2 / math.pi)))

    def theta_from_t(self, t):
        """Return the paper's parameter theta = t + theta_T2 [rad]."""
        return np.asarray(t, dtype=float) + self.theta_T2

    def t_from_theta(self, theta):
        """Return t = theta - theta_T2 [rad]."""
        return np.asarray(theta, dtype=float) - self.theta_T2

    def radius_of_curvature(self, theta):
        """Return rho(theta) by the paper's eq. (34), shape of ``theta`` [m]."""
        theta = np.asarray(theta, dtype=float)
        a, b = self.a, self.b
        return (a * a * np.sin(theta) ** 2 + b * b * np.cos(theta) ** 2) ** 1.5 / (a * b)

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


def _blend_shape(u):
    """
    Return f(u) = u**2 (1 - u)**3 / 2 and its first three derivatives, u in [0, 1].

    f(0) = f'(0) = 0, f''(0) = 1 and f = f' = f'' = 0 at u = 1: subtracted from
    the ellipse with the right scale it cancels the curvature at the vertical
    line and vanishes to second order where it meets the ellipse.
    """
    return ((u ** 2 - 3.0 * u ** 3 + 3.0 * u ** 4 - u ** 5) / 2.0,
            (2.0 * u - 9.0 * u ** 2 + 12.0 * u ** 3 - 5.0 * u ** 4) / 2.0,
            1.0 - 9.0 * u + 18.0 * u ** 2 - 10.0 * u ** 3,
            -9.0 + 36.0 * u - 30.0 * u ** 2)


@dataclass(frozen=True, eq=False)
class BlendedArc(_ParametricArc):
    """
    The ellipse with curvature-continuous (G2) transitions at T1 and T2, paper frame.

    Q(t) = P(t) + (delta(t), 0): the ellipse bent horizontally near its ends.
    Near T1 (u = (pi - t) / span_1 < 1) delta = -l span_1**2 f(u), near T2
    (u = t / span_2 < 1) delta = +l span_2**2 f(u), elsewhere 0, with the quintic
    f(u) = u**2 (1 - u)**3 / 2 (:func:`_blend_shape`). Since d2P/dt2 = -P,
    x'' = -l cos t + delta'' is 0 at T1 and T2: the curvature starts and ends at
    0 (the vertical line's), the tangent stays vertical there, and at u = 1 the
    bent curve meets the ellipse with equal position, tangent and curvature
    (delta, delta', delta'' all vanish). Why this transition and not a
    clothoid: it is closed-form in the ellipse's own parameter (exact
    derivatives to the third, hence exact curvature and dkappa/ds for the
    timing, no Fresnel integrals), it needs no shift of the ellipse (the
    vertical lines and the ellipse beyond the transition stay the paper's),
    heights are untouched (delta is horizontal, so the apex height is the
    paper's), and the deviation from the paper's path is bounded in closed
    form: |delta| <= l span**2 max f = l span**2 * 54/3125. The price: any
    transition that starts on the vertical line and ends on the ellipse must
    turn as much as the ellipse does over the same stretch, so its curvature
    overshoots the ellipse's (by up to ~37 % here), and it rises with
    dkappa/ds about 9 kappa_T / (transition length) at T1 and T2.

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
    _panel_t: np.ndarray = field(init=False, repr=False)
    _panel_s: np.ndarray = field(init=False, repr=False)
    _panel_speed: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        if not isinstance(self.ellipse, EllipticArc):
            raise InvalidInputError(
                f'ellipse: expected an EllipticArc, got {type(self.ellipse).__name__}')
        for name in ('span_1', 'span_2'):
            require_range(name, getattr(self, name), 0.0, _BLEND_MAX_SPAN, low_open=True,
                          unit='rad')
        self._build_length_table((math.pi - self.span_1, self.span_2))

    def offset(self, t):
        """Return delta and its first three derivatives by t, each of the shape of ``t``."""
        t = np.asarray(t, dtype=float)
        flat = t.reshape(-1)
        out = np.zeros((4, flat.size))
        l_ = self.ellipse.l
        for span, u, sign in ((self.span_1, (math.pi - flat) / self.span_1, -1.0),
                              (self.span_2, flat / self.span_2, 1.0)):
            near = np.flatnonzero(u < 1.0)
            if near.size == 0:
                continue
            f, f1, f2, f3 = _blend_shape(u[near])
            # d/dt = -(1/span) d/du near T1 (u grows as t falls), +(1/span) d/du near T2.
            out[0, near] = sign * l_ * span ** 2 * f
            out[1, near] = l_ * span * f1
            out[2, near] = sign * l_ * f2
            out[3, near] = l_ * f3 / span
        return out.reshape((4,) + t.shape)

    def derivatives(self, t):
        """Return Q and its first three derivatives by t, each (N, 2) [m, m/rad, ...]."""
        p, d1, d2, d3 = self.ellipse.derivatives(t)
        delta = self.offset(t)
        for value, extra in zip((p, d1, d2, d3), delta):
            value[:, 0] += extra
        return p, d1, d2, d3

    def point(self, t):
        """Return points Q(t), shape (N, 2) [m]."""
        return self.derivatives(np.atleast_1d(t))[0]

    def speed(self, t):
        """Return |dQ/dt| [m/rad], shape of ``t``."""
        t = np.asarray(t, dtype=float)
        ellipse = self.ellipse
        delta_1 = self.offset(t)[1]
        sin_t, cos_t = np.sin(t), np.cos(t)
        return np.sqrt((delta_1 - ellipse.l * sin_t) ** 2
                       + (ellipse.k * cos_t - ellipse.h * sin_t) ** 2)

    def _dense(self):
        t = np.linspace(math.pi, 0.0, _DENSE_SAMPLES)
        return t, self.curvature_and_rate(t)[0]

    @property
    def min_radius(self):
        """Smallest radius of curvature on the bent arc [m] (dense sampling)."""
        return 1.0 / float(self._dense()[1].max())

    @property
    def tightest_t(self):
        """Parameter t of the largest curvature (dense sampling) [rad]."""
        t, kappa = self._dense()
        return float(t[int(np.argmax(kappa))])

    @property
    def end_radius(self):
        """Radius of curvature at T1 and T2: infinite (the curvature is 0 there)."""
        return math.inf

    def max_deviation(self):
        """Bound on the horizontal distance from the ellipse [m]: l span**2 max f."""
        return self.ellipse.l * max(self.span_1, self.span_2) ** 2 * _BLEND_PEAK


def blend_arc(ellipse, tolerance=DEFAULT_JOIN_TOLERANCE):
    """
    Return the :class:`BlendedArc` of ``ellipse`` that deviates at most ``tolerance``.

    Each transition is as long as the tolerance allows (a longer one raises the
    curvature more gently, which lets the motion through it faster), but ends
    before ``_BLEND_APEX_SHARE`` of the way to the apex and within
    ``_BLEND_MAX_SPAN``; spans are halved while the bent curve would slow its
    parameter speed to below ``_BLEND_MIN_SPEED_SHARE`` of the ellipse's.
    """
    tolerance = require_range('join_tolerance', tolerance, 0.0, 0.01, low_open=True, unit='m')
    widest = math.sqrt(tolerance / (_BLEND_PEAK * ellipse.l))
    t_apex = math.atan2(ellipse.k, ellipse.h)
    span_1 = min(widest, _BLEND_APEX_SHARE * (math.pi - t_apex), _BLEND_MAX_SPAN)
    span_2 = min(widest, _BLEND_APEX_SHARE * t_apex, _BLEND_MAX_SPAN)
    t = np.linspace(math.pi, 0.0, _DENSE_SAMPLES)
    slowest = float(ellipse.speed(t).min())
    for _ in range(20):
        bent = BlendedArc(ellipse, span_1, span_2)
        if float(bent.speed(t).min()) >= _BLEND_MIN_SPEED_SHARE * slowest:
            return bent
        span_1, span_2 = 0.5 * span_1, 0.5 * span_2
    raise DegenerateGeometryError(
        f'join: expected a regular G2 transition for l = {ellipse.l:.6g} m, '
        f'h = {ellipse.h:.6g} m, got none; use join paper')


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
    bend: object = None
    join: str = 'paper'

    def __post_init__(self):
        if self.join not in JOINS:
            raise InvalidInputError(
                f'join: expected one of {", ".join(JOINS)}, got {self.join!r}')
        if self.bend is None:
            object.__setattr__(self, 'bend', self.arc)

    @property
    def segment_ends(self):
        """Arc length at P1, T1, T2, P2 [m], shape (4,)."""
        return np.concatenate(([0.0], np.cumsum(self.segment_lengths)))

    @property
    def length(self):
        """Total path length [m]."""
        return float(np.sum(self.segment_lengths))

    @property
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

    def evaluate(self, s):
        """
        Sample the path at arc lengths ``s`` (N,) [m], clipped to [0, length].

        Returns
        -------
        PathSamples
            Position, unit tangent and the second and third derivatives by s.

        """
        s = np.clip(np.atleast_1d(np.asarray(s, dtype=float)), 0.0, self.length)
        count = s.shape[0]
        position = np.empty((count, 3))
        tangent = np.zeros((count, 3))
        curvature = np.zeros((count, 3))
        rate = np.zeros((count, 3))
        s_t1, s_t2 = self.segment_ends[1], self.segment_ends[2]
        if self.arc is None:
            line = (self.place - self.pick) / self.length
            position[:] = self.pick + s[:, None] * line
            tangent[:] = line
            return PathSamples(position, tangent, curvature, rate)
        up = np.array([0.0, 0.0, 1.0])
        lift = (s <= s_t1) & (self.segment_lengths[0] > 0.0)
        position[lift] = self.pick + s[lift, None] * up
        tangent[lift] = up
        descent = (s >= s_t2) & ~lift & (self.segment_lengths[2] > 0.0)
        position[descent] = self.tangent_2 - (s[descent, None] - s_t2) * up
        tangent[descent] = -up
        on_arc = ~(lift | descent)
        if np.any(on_arc):
            self._evaluate_arc(s[on_arc] - s_t1, on_arc, position, tangent, curvature, rate)
        return PathSamples(position, tangent, curvature, rate)

    def _evaluate_arc(self, s_arc, mask, position, tangent, curvature, rate):
        """Fill the bend samples: derivatives by s from those by t (g = ds/dt = -|P'|)."""
        bend = self.bend
        t = bend.t_from_s(s_arc)
        p, d1, d2, d3 = bend.derivatives(t)
        sigma = np.linalg.norm(d1, axis=-1)
        sigma_1 = np.einsum('ij,ij->i', d1, d2) / sigma
        sigma_2 = ((np.einsum('ij,ij->i', d2, d2) + np.einsum('ij,ij->i', d1, d3)) / sigma
                   - sigma_1 ** 2 / sigma)
        g, g1, g2 = -sigma, -sigma_1, -sigma_2
        r_s = d1 / g[:, None]
        r_ss = (d2 - g1[:, None] * r_s) / (g * g)[:, None]
        r_sss = (d3 - g2[:, None] * r_s - 3.0 * (g * g1)[:, None] * r_ss) / (g ** 3)[:, None]
        position[mask] = self.to_base(p)
        vertical = np.array([0.0, 0.0, 1.0])
        for out, value in ((tangent, r_s), (curvature, r_ss), (rate, r_sss)):
            out[mask] = value[:, :1] * self.direction + value[:, 1:2] * vertical


def require_coordinates(name, point):
    """Return ``point`` as a (3,) array of finite coordinates within +-10 m."""
    point = require_point(name, point)
    if np.abs(point).max() > _MAX_COORDINATE:
        raise InvalidInputError(
            f'{name}: expected coordinates within +-{_MAX_COORDINATE:g} m, got {point.tolist()}')
    return point


def plan_path(pick, place, pick_clearance=0.025, place_clearance=0.025, policy=None,
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
    c1 = require_range('pick_clearance', pick_clearance, 0.0, 1.0, unit='m')
    c2 = require_range('place_clearance', place_clearance, 0.0, 1.0, unit='m')
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
