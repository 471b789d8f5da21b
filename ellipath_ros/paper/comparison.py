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
The comparison paths of the paper's Figure 8, in the paper frame.

The paper compares its arc with "the symmetric bisect elliptical path", a Lamé
curve |u/d|**m + |v/e|**m = 1 with d = 0.05, e = 0.025 and one with d = 0.15,
e = 0.025 (width 300 mm, lift height 50 mm: l = 0.15, h = 0.025), but says
neither where these curves sit nor the exponent m. Our assumptions:

* Every path runs from T1 = (-l, -h) to T2 = (l, h) and leaves and reaches
  them vertically, like the proposed arc, so all paths join the same vertical
  segments and their lengths compare like for like.
* The comparison curves are symmetric: they start and end at the level of the
  HIGHER tangent point, y = |h|. The lower side is extended by a vertical
  straight line of length 2 |h| (at T1 when h > 0, at T2 when h < 0).
* Lamé paths are the corner construction of Gauthier et al. (the paper's
  ref. 10): a quarter Lamé curve of half-width d and height e at each corner,
  centred at (-(l - d), |h|) and (l - d, |h|), joined by a horizontal
  straight line of length 2 (l - d) at height |h| + e. With d = l (the
  paper's d = 0.15) the quarters meet at the top: half a Lamé curve.
* Exponent m = 4: the smallest even exponent above 2. Any m > 2 makes the
  curvature vanish where the curve meets the straight lines (G2 joins, the
  reason Lamé curves are used there); an even m keeps the length integrand
  analytic. m = 2 would make the corners quarter ellipses.
* The paper's d = 0.05 and 0.15 are l/3 and l on its example; for other l we
  keep these fractions (``_PAPER_LAME_D_FRACTIONS``). e stays 0.025 m.
* The symmetric bisected ellipse is axis-aligned, centred at (0, |h|), with
  horizontal semi-axis l (forced by the vertical tangents at u = +-l) and
  vertical semi-axis ``rise`` = 0.025 m, the Lamé curves' e: all three
  comparison paths then have the same apex, 2 |h| + 0.025 m above the lower
  tangent point. (It is the Lamé path with d = l and m = 2.)

Lengths: the proposed arc and the symmetric ellipse exactly (complete elliptic
integral by the AGM); a Lamé quarter by composite Gauss-Legendre quadrature
in the normalised polar angle (relative error ~1e-15 for m = 4).

Every comparison path is at least 2 l + 2 |h| long (horizontal span plus the
vertical extension), whatever its rise or exponent; on the paper's example the
proposed arc (0.3237 m) is shorter than that bound (0.35 m), so the paper's
claim holds there independently of these assumptions. It does not hold for
every geometry: for small |h| the paper's rule picks a tall arc (the semicircle
at h = 0) that is longer than the Lamé paths (see docs/paper_reproduction.md).
"""

from dataclasses import dataclass
import math

from ellipath_ros.core.errors import InvalidInputError, require_range
from ellipath_ros.core.geometry import (
    arc_for_policy, ArcPolicy, elliptic_e, GAUSS_LEGENDRE_NODES, GAUSS_LEGENDRE_WEIGHTS,
    require_finite_h)
import numpy as np

# The paper's Lamé curves: d = 0.05 and 0.15 m for l = 0.15 m, i.e. l / 3 and l.
_PAPER_LAME_D_FRACTIONS = (1.0 / 3.0, 1.0)
# The paper's Lamé height e [m]; also the rise of the symmetric ellipse.
_PAPER_LAME_E = 0.025
# Assumed Lamé exponent (the paper does not state it).
_DEFAULT_EXPONENT = 4.0
# Default samples per curved piece of a comparison path: a smooth line in Figure 8 (lengths
# come from quadrature, not from these samples).
_DEFAULT_SAMPLES = 201

_LAME_PANELS = 256


@dataclass(frozen=True, eq=False)
class ComparisonPath:
    """
    One path of Figure 8, sampled in the paper frame.

    Attributes
    ----------
    name : str
        Short machine name, e.g. ``'proposed'``, ``'symmetric_ellipse'``,
        ``'lame_d0.05'``.
    label : str
        Human-readable description (for a legend).
    points : numpy.ndarray
        Samples from T1 = (-l, -h) to T2 = (l, h), shape (N, 2) [m], paper frame
        (horizontal, vertical), vertical extensions included.
    length : float
        Length from T1 to T2 [m], vertical extensions included.
    apex_height : float
        Height of the highest point above the lower tangent point [m].

    """

    name: str
    label: str
    points: np.ndarray
    length: float
    apex_height: float


def _require_samples(samples):
    """Return ``samples`` as an int >= 2, or raise."""
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 2:
        raise InvalidInputError(f'samples: expected an integer >= 2, got {samples!r}')
    return int(samples)


def _require_exponent(m):
    """Return the Lamé exponent as float in [2, 100], or raise."""
    return require_range('m', m, 2.0, 100.0)


def _unit_lame(psi, m):
    """
    Return the unit Lamé quarter |x|**m + |y|**m = 1 by normalised polar angle.

    Parameters
    ----------
    psi : numpy.ndarray
        Polar angles in [0, pi/2] [rad], any shape.
    m : float
        Exponent, >= 2.

    Returns
    -------
    rho, rho_dot : numpy.ndarray
        Polar radius and its derivative by psi, shape of ``psi``.

    """
    c, s = np.cos(psi), np.sin(psi)
    # Clip the rounding noise of cos(pi/2) so that fractional powers stay real.
    c, s = np.clip(c, 0.0, 1.0), np.clip(s, 0.0, 1.0)
    total = c ** m + s ** m
    rho = total ** (-1.0 / m)
    rho_dot = -rho * (s ** (m - 1.0) * c - c ** (m - 1.0) * s) / total
    return rho, rho_dot


def lame_quarter_points(d, e, m=_DEFAULT_EXPONENT, samples=_DEFAULT_SAMPLES):
    """
    Sample the quarter Lamé curve |u/d|**m + |v/e|**m = 1, u, v >= 0.

    Parameters
    ----------
    d, e : float
        Half-width and height [m], > 0.
    m : float
        Exponent, in [2, 100].
    samples : int
        Number of points, >= 2.

    Returns
    -------
    numpy.ndarray
        Points from (d, 0) to (0, e) relative to the curve's centre, shape
        (samples, 2) [m], evenly spaced in the normalised polar angle.

    """
    d = require_range('d', d, 0.0, low_open=True, unit='m')
    e = require_range('e', e, 0.0, low_open=True, unit='m')
    m = _require_exponent(m)
    psi = np.linspace(0.0, 0.5 * math.pi, _require_samples(samples))
    rho, _ = _unit_lame(psi, m)
    points = np.stack((d * rho * np.cos(psi), e * rho * np.sin(psi)), axis=-1)
    # Exact ends (cos(pi/2) is not 0 in floating point).
    points[0], points[-1] = (d, 0.0), (0.0, e)
    return points


def lame_quarter_length(d, e, m=_DEFAULT_EXPONENT):
    """
    Return the length of the quarter Lamé curve |u/d|**m + |v/e|**m = 1 [m].

    Composite 8-point Gauss-Legendre quadrature over 256 panels of the
    normalised polar angle psi, with (u, v) = rho(psi) (d cos psi, e sin psi).

    Parameters
    ----------
    d, e : float
        Half-width and height [m], > 0.
    m : float
        Exponent, in [2, 100]; m = 2 gives a quarter ellipse.

    """
    d = require_range('d', d, 0.0, low_open=True, unit='m')
    e = require_range('e', e, 0.0, low_open=True, unit='m')
    m = _require_exponent(m)
    edges = np.linspace(0.0, 0.5 * math.pi, _LAME_PANELS + 1)
    half = 0.5 * np.diff(edges)
    psi = (0.5 * (edges[1:] + edges[:-1]))[:, None] + half[:, None] * GAUSS_LEGENDRE_NODES
    rho, rho_dot = _unit_lame(psi, m)
    c, s = np.cos(psi), np.sin(psi)
    speed = np.hypot(d * (rho_dot * c - rho * s), e * (rho_dot * s + rho * c))
    return float(np.sum(half * (speed @ GAUSS_LEGENDRE_WEIGHTS)))


def half_ellipse_length(p, q):
    """Return half the perimeter of an ellipse of semi-axes ``p``, ``q`` [m] (exact, AGM)."""
    p = require_range('p', p, 0.0, low_open=True, unit='m')
    q = require_range('q', q, 0.0, low_open=True, unit='m')
    major, minor = max(p, q), min(p, q)
    return 2.0 * major * elliptic_e(1.0 - (minor / major) ** 2)


def _join(half_width, h, top):
    """
    Add the vertical extension on the lower side to a curve at level |h|.

    Parameters
    ----------
    half_width, h : float
        Half-width l and half-rise [m].
    top : numpy.ndarray
        Curve from (-l, |h|) to (l, |h|), shape (N, 2) [m].

    Returns
    -------
    numpy.ndarray
        Path from (-l, -h) to (l, h), shape (M, 2) [m], consecutive duplicates dropped.

    """
    pieces = [top]
    if h > 0.0:
        pieces.insert(0, np.array([[-half_width, -h]]))
    elif h < 0.0:
        pieces.append(np.array([[half_width, h]]))
    points = np.vstack(pieces)
    keep = np.concatenate(([True], np.any(np.diff(points, axis=0) != 0.0, axis=1)))
    return points[keep]


def symmetric_ellipse_path(half_width, h, rise=_PAPER_LAME_E, samples=_DEFAULT_SAMPLES):
    """
    Return the symmetric bisected ellipse path (Figure 8, green).

    Axis-aligned half ellipse centred at (0, |h|), semi-axes l (horizontal) and
    ``rise`` (vertical), plus the vertical line on the lower side.

    Parameters
    ----------
    half_width : float
        l, half the horizontal distance between the tangent points [m], > 0.
    h : float
        Half-rise from T1 to T2 [m], any sign.
    rise : float
        Vertical semi-axis [m], > 0: the apex is ``rise`` above the higher
        tangent point.
    samples : int
        Points on the half ellipse, >= 2.

    Returns
    -------
    ComparisonPath

    """
    half_width = require_range('half_width', half_width, 0.0, low_open=True, unit='m')
    h = require_finite_h(h)
    rise = require_range('rise', rise, 0.0, low_open=True, unit='m')
    t = np.linspace(math.pi, 0.0, _require_samples(samples))
    top = np.stack((half_width * np.cos(t), abs(h) + rise * np.sin(t)), axis=-1)
    return ComparisonPath(
        'symmetric_ellipse', f'symmetric ellipse ({rise * 1e3:g} mm rise)',
        _join(half_width, h, top), half_ellipse_length(half_width, rise) + 2.0 * abs(h),
        2.0 * abs(h) + rise)


def lame_path(half_width, h, d, e=_PAPER_LAME_E, m=_DEFAULT_EXPONENT,
              samples=_DEFAULT_SAMPLES):
    """
    Return a Lamé-corner path (Figure 8, blue and black).

    Quarter Lamé curves of half-width ``d`` and height ``e`` at both corners,
    centred at (-(l - d), |h|) and (l - d, |h|), a horizontal line between
    them, and the vertical line on the lower side.

    Parameters
    ----------
    half_width : float
        l, half the horizontal distance between the tangent points [m], > 0.
    h : float
        Half-rise from T1 to T2 [m], any sign.
    d : float
        Corner half-width [m], in (0, l].
    e : float
        Corner height [m], > 0: the apex clearance above the higher tangent point.
    m : float
        Lamé exponent, in [2, 100].
    samples : int
        Points per corner, >= 2.

    Returns
    -------
    ComparisonPath

    """
    half_width = require_range('half_width', half_width, 0.0, low_open=True, unit='m')
    h = require_finite_h(h)
    d = require_range('d', d, 0.0, half_width, low_open=True, unit='m')
    quarter = lame_quarter_points(d, e, m, samples)
    centre = np.array([half_width - d, abs(h)])
    left = centre * [-1.0, 1.0] + quarter * [-1.0, 1.0]
    right = (centre + quarter)[::-1]
    straight = 2.0 * (half_width - d)
    return ComparisonPath(
        f'lame_d{d:g}', f'Lamé m={m:g}, d={d * 1e3:g} mm, e={e * 1e3:g} mm',
        _join(half_width, h, np.vstack((left, right))),
        2.0 * lame_quarter_length(d, e, m) + straight + 2.0 * abs(h), 2.0 * abs(h) + e)


def proposed_path(arc, samples=_DEFAULT_SAMPLES, label='proposed asymmetric ellipse'):
    """
    Return the proposed arc as a ComparisonPath (Figure 8, red).

    Parameters
    ----------
    arc : EllipticArc
        The arc, paper frame.
    samples : int
        Points on the arc, >= 2.
    label : str
        Legend text.

    Returns
    -------
    ComparisonPath
        Exact length (AGM) and the apex height above the lower tangent point.

    """
    t = np.linspace(math.pi, 0.0, _require_samples(samples))
    return ComparisonPath('proposed', label, arc.point(t), arc.length, arc.apex_height)


def figure8_paths(half_width, h, policy=None, e=_PAPER_LAME_E, m=_DEFAULT_EXPONENT,
                  samples=_DEFAULT_SAMPLES):
    """
    Return the four paths of the paper's Figure 8 for half-width l and half-rise h.

    Parameters
    ----------
    half_width : float
        l, half the horizontal distance between the tangent points [m], > 0.
    h : float
        Half-rise from T1 to T2 [m], any sign.
    policy : ArcPolicy, optional
        Arc policy of the proposed path; the paper's rule by default.
    e : float
        Lamé height and symmetric-ellipse rise [m], > 0.
    m : float
        Lamé exponent, in [2, 100].
    samples : int
        Points per curved piece, >= 2.

    Returns
    -------
    tuple of ComparisonPath
        (proposed, symmetric ellipse, Lamé d = l/3, Lamé d = l).

    """
    policy = policy or ArcPolicy()
    arc = arc_for_policy(half_width, h, policy)
    label = 'proposed (paper rule)' if policy.kind == 'paper' else f'proposed ({policy.kind})'
    return (proposed_path(arc, samples, label), symmetric_ellipse_path(half_width, h, e, samples),
            *(lame_path(half_width, h, fraction * half_width, e, m, samples)
              for fraction in _PAPER_LAME_D_FRACTIONS))
