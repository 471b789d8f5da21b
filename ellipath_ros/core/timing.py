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
Timing laws along a :class:`~ellipath_ros.core.geometry.PickPlacePath`.

Two profiles, one entry point (:func:`time_motion`):

``curvature`` (the paper's, section 2.3)
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

``time_optimal`` (beyond the paper)
    The fastest motion found along the same path with speed <= max_speed,
    acceleration vector norm <= max_accel (tangential s'' and normal
    s'**2 kappa together), jerk vector norm <= max_jerk (jerk =
    p''' s'**3 + 3 p'' s' s'' + p' s''', p = p(s)), acceleration step at
    T1/T2 (s'**2 times the arc's end curvature, the lines being straight)
    <= max_accel_jump, an optional speed cap s' <= speed_cap(s), from rest to
    rest. See :func:`time_motion` for the construction.

Both profiles return a :class:`TimedMotion`. The constructions aim at
``*_MARGIN`` of the limits; the result is then sampled (every
``SAFETY_CHECK_PERIOD``, at most ``SAFETY_CHECK_SAMPLES`` samples) and, should
a limit or the speed cap be broken there after all, slowed down uniformly in
time until it is not.

Arrays: times t have shape (N,) [s]; path states (s, s', s'', s''') have
shape (N,) [m, m/s, m/s**2, m/s**3]; Cartesian arrays have shape (N, 3), base
frame, SI units.
"""

from bisect import bisect_right
from dataclasses import dataclass, field, replace
import math

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from .errors import InvalidInputError, LimitError, require_range
from .geometry import PickPlacePath
from .settings import validate_fields

PROFILES = ('curvature', 'time_optimal')

# The construction aims at these fractions of the limits; the rest absorbs what happens
# between the steps it is built from (the final check samples the continuous motion).
SPEED_MARGIN = 0.999
ACCEL_MARGIN = 0.995
JERK_MARGIN = 0.995
# Time step of the path-space scans [s]: the short one where the curvature (1/m) is above
# SCAN_KAPPA, where the limits change fast along the path.
SCAN_STEP = 1e-3
SCAN_STEP_SHORT = 5e-4
SCAN_KAPPA = 8.0
# ... and shorter still where the curvature changes by more than this share within a step
# (not below SCAN_STEP_MIN).
SCAN_KAPPA_CHANGE = 0.1
SCAN_STEP_MIN = 2e-5
# Sample period of the final limit check [s] and the default of TimedMotion.metrics [s].
SAFETY_CHECK_PERIOD = 2.5e-4
SAFETY_CHECK_SAMPLES = 4000
SAFETY_REFINE = 8
SAFETY_SLACK = 2e-3
CHECK_PERIOD = 1e-4
METRICS_SAMPLES = 100000
# Grid of the curvature tables along the arc (intervals; more for very tight bends).
TABLE_INTERVALS = 2048
TABLE_INTERVALS_MAX = 16384
# Samples of a stretch for constant limits that hold all along it (plus the tightest point).
LIMIT_SAMPLES = 129
# Share of the jerk budget the scans give the normal component (3 kappa v a + kappa_s v**3),
# leaving the rest for changing the tangential acceleration.
NORMAL_JERK_SHARE = 0.9
# Levelling off looks ahead by the distance it takes at least at this share of max_accel.
LEVEL_REACH = 0.1
# A scan slowing down below this speed [m/s] stops (the other scan covers the rest).
MIN_SCAN_SPEED = 1e-3
# Share of the jerk available in the state with which a scan ramps its acceleration down when
# it levels off at the speed limit.
LEVEL_OFF_JERK = 0.9
# A scan that cannot follow a falling acceleration bound backs up this many steps and lowers
# its acceleration target by this factor over the troubled stretch, at most this often.
BACK_UP_STEPS = 20
BACK_UP_AHEAD = 5e-3
BACK_UP_FACTOR = 0.75
BACK_UP_LIMIT = 30
# Interior speed valleys: first try at this share of the local speed ceiling, then lower.
VALLEY_SHARE = 0.9
VALLEY_RETRY_FACTOR = 0.6
VALLEY_TRIES = 4
VALLEY_DEPTH = 6
# Valleys are looked for this far [m] beyond where the scans stopped.
VALLEY_REACH = 0.02
# An end speed (T1, T2) the arc cannot take comes down by this factor, at most this often.
END_RETRY_FACTOR = 0.8
END_TRIES = 12
# Stretches solved per plan before giving up on the scans (the fallback then serves).
HILL_BUDGET = 40
# The sure but slow construction, when the scans find nothing: Ruckig pieces between knots.
FALLBACK_PIECES = 24
# Steps both scans go on past their crossing, room for the piece that joins them.
JOIN_ROOM_STEPS = 40
# Share of the acceleration and jerk limits that cruising (s'' = 0) uses at the ceiling that
# places speed valleys.
CEILING_SHARE = 0.9
# The speed cap along the arc is taken as stairs this many table cells long.
CAP_STAIR = 8
# Where a ramp may end, in shares of the arc's parameter range, after the nodes.
RAMP_FRACTIONS = np.array([1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.2])
# The paper's node list is refused beyond this many nodes (r far too small).
MAX_NODES = 20000
# Time table of the curvature law: Gauss-Legendre panels over the arc.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_ODE_PANELS = 256
_BASELINE_SAMPLES = 4001


@dataclass(frozen=True)
class CartesianLimits:
    """
    Limits of the TCP motion.

    Attributes
    ----------
    max_speed : float
        Largest TCP speed [m/s], > 0.
    max_accel : float
        Largest norm of the TCP acceleration vector [m/s**2], > 0; the normal
        part v**2 kappa counts.
    max_jerk : float
        Largest norm of the TCP jerk vector [m/s**3], > 0.
    max_accel_jump : float
        Largest step of the acceleration vector at T1 and T2 [m/s**2], >= 0.
        The curvature jumps from 0 (line) to 1/rho_T (arc end) there, so the
        normal acceleration steps by v**2 / rho_T; a step in commanded
        acceleration is a step in motor torque, which excites the arms. The
        default, 25 m/s**2 (half of ``max_accel``), keeps that step moderate
        and costs little: it caps the speed at T1/T2 at sqrt(25 rho_T)
        (0.46 m/s on the paper's example) where the curvature limit alone
        allows about 0.65 m/s. 0 makes the motion stop at T1 and T2.

    """

    max_speed: float = 4.0
    max_accel: float = 50.0
    max_jerk: float = 5000.0
    max_accel_jump: float = 25.0

    def __post_init__(self):
        # Practical ranges (core/settings.py): beyond them a motion lasts hours or the
        # arithmetic overflows.
        validate_fields(self)


# -- laws: s(t) and its derivatives -----------------------------------------------------------

@dataclass(frozen=True, eq=False)
class _JerkPieces:
    """s(t) with piecewise-constant jerk: piece i starts at ``times[i]`` in state (s, v, a)."""

    times: np.ndarray  # (K + 1,) [s], from 0
    s0: np.ndarray  # (K,) [m]
    v0: np.ndarray  # (K,) [m/s]
    a0: np.ndarray  # (K,) [m/s**2]
    jerk: np.ndarray  # (K,) [m/s**3]

    @property
    def duration(self):
        return float(self.times[-1])

    def state(self, t):
        """Return (s, v, a, j), each shaped like ``t`` (N,)."""
        index = np.clip(np.searchsorted(self.times, t, side='right') - 1, 0, self.jerk.size - 1)
        x = t - self.times[index]
        j, a, v = self.jerk[index], self.a0[index], self.v0[index]
        return (self.s0[index] + x * (v + x * (a / 2.0 + x * j / 6.0)),
                v + x * (a + x * j / 2.0), a + x * j, j)


class _PieceList:
    """Collects constant-jerk pieces (duration, s, v, a, j) into a :class:`_JerkPieces`."""

    def __init__(self):
        self.rows = []

    def add(self, duration, s, v, a, j):
        if duration > 0.0:
            self.rows.append((duration, s, v, a, j))

    def extend(self, rows, s_offset=0.0):
        for duration, s, v, a, j in rows:
            self.add(duration, s + s_offset, v, a, j)

    def law(self):
        rows = np.array(self.rows, dtype=float).reshape(-1, 5)
        times = np.concatenate(([0.0], np.cumsum(rows[:, 0])))
        return _JerkPieces(times, rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4])


@dataclass(frozen=True, eq=False)
class _CurvatureArcLaw:
    """
    The paper's law on the arc: d theta/dt = -K rho(theta), from theta_start down to theta_end.

    With sigma = |dP/dtheta| = sqrt(a**2 sin**2 + b**2 cos**2) and rho = sigma**3 / (a b):
    s' = K sigma**4 / (a b), s'' = -4 K**2 sigma**6 sigma_1 / (a b)**2,
    s''' = 4 K**3 sigma**8 (6 sigma_1**2 + sigma sigma_2) / (a b)**3 (sigma_i: derivatives
    by theta), and t(theta) = (a b / K) * integral of sigma**-3 from theta to theta_start.
    """

    arc: object
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

    def _sigma(self, theta):
        a, b = self.arc.a, self.arc.b
        return np.sqrt(a * a * np.sin(theta) ** 2 + b * b * np.cos(theta) ** 2)

    def _elapsed(self, theta_from, theta_to):
        """Return the time from theta_from down to theta_to (elementwise), >= 0."""
        half = 0.5 * (theta_to - theta_from)
        nodes = (0.5 * (theta_to + theta_from))[..., None] + half[..., None] * _GL_NODES
        ab = self.arc.a * self.arc.b
        return np.abs(half) * ab / self.rate * (self._sigma(nodes) ** -3 @ _GL_WEIGHTS)

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
            theta = np.clip(theta + residual * self.rate * self._sigma(theta) ** 3 / ab,
                            theta_1, theta_0)
        return theta

    def state(self, t):
        theta = self.theta(t)
        a, b, rate = self.arc.a, self.arc.b, self.rate
        ab = a * b
        sigma = self._sigma(theta)
        sigma_1 = (a * a - b * b) * np.sin(2.0 * theta) / (2.0 * sigma)
        sigma_2 = ((a * a - b * b) * np.cos(2.0 * theta) - sigma_1 ** 2) / sigma
        s = self.s_offset + self.arc.s_from_t(self.arc.t_from_theta(theta))
        speed = rate * sigma ** 4 / ab
        accel = -4.0 * rate ** 2 * sigma ** 6 * sigma_1 / ab ** 2
        jerk = 4.0 * rate ** 3 * sigma ** 8 * (6.0 * sigma_1 ** 2 + sigma * sigma_2) / ab ** 3
        return s, speed, accel, jerk


@dataclass(frozen=True, eq=False)
class _Sequence:
    """Laws run one after the other."""

    laws: tuple

    @property
    def duration(self):
        return float(sum(law.duration for law in self.laws))

    def state(self, t):
        starts = np.cumsum([0.0] + [law.duration for law in self.laws])
        which = np.clip(np.searchsorted(starts, t, side='right') - 1, 0, len(self.laws) - 1)
        out = [np.empty_like(t) for _ in range(4)]
        for index, law in enumerate(self.laws):
            mask = which == index
            if np.any(mask):
                for target, value in zip(out, law.state(t[mask] - starts[index])):
                    target[mask] = value
        return tuple(out)


# -- the result -------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class TimedMotion:
    """
    A timed motion along a path (build it with :func:`time_motion`).

    Attributes
    ----------
    path : PickPlacePath
        The geometric path.
    profile : str
        One of ``PROFILES``.
    duration : float
        Total time [s].
    segment_durations : numpy.ndarray
        Time on the lift, the arc and the descent [s], shape (3,). A pure
        vertical move counts as lift (going up) or descent (going down).
    accel_jump_T1, accel_jump_T2 : float
        Step of the acceleration vector at T1 and T2 [m/s**2].
    n_nodes : int or None
        Nodes of the paper's node list (curvature profile), else None.
    law : object
        The timing law s(t) it was built from (internal; read it through
        :meth:`path_state`).
    time_scale : float
        Uniform slow-down applied to ``law`` (>= 1).
    node_period : float or None
        The paper's fixed time step Delta t between nodes [s] (curvature
        profile: r / K), else None.

    """

    path: PickPlacePath
    profile: str
    duration: float
    segment_durations: np.ndarray
    accel_jump_T1: float
    accel_jump_T2: float
    n_nodes: object
    law: object = field(repr=False)
    time_scale: float = 1.0
    node_period: object = None

    def __post_init__(self):
        if not isinstance(self.path, PickPlacePath):
            raise InvalidInputError(
                f'path: expected a PickPlacePath, got {type(self.path).__name__}')
        if self.profile not in PROFILES:
            raise InvalidInputError(
                f'profile: expected one of {", ".join(PROFILES)}, got {self.profile!r}')
        require_range('time_scale', self.time_scale, 1.0, math.inf)
        duration = require_range('duration', self.duration, 0.0, math.inf, low_open=True,
                                 unit='s')
        segments = np.asarray(self.segment_durations, dtype=float)
        if (segments.shape != (3,) or not np.all(np.isfinite(segments))
                or np.any(segments < 0.0) or abs(segments.sum() - duration) > 1e-9 * duration):
            raise InvalidInputError(
                f'segment_durations: expected 3 non-negative times summing to the duration '
                f'{duration:.9g} s, got {segments.tolist()}')
        object.__setattr__(self, 'segment_durations', segments)
        for name in ('accel_jump_T1', 'accel_jump_T2'):
            require_range(name, getattr(self, name), 0.0, math.inf, unit='m/s^2')
        if self.node_period is not None:
            require_range('node_period', self.node_period, 0.0, math.inf, low_open=True,
                          unit='s')

    def path_state(self, t):
        """
        Return the path state at times ``t``.

        Parameters
        ----------
        t : array_like
            Times [s], shape (N,), within [0, duration].

        Returns
        -------
        tuple of numpy.ndarray
            (s, s', s'', s''') [m, m/s, m/s**2, m/s**3], each of shape (N,).

        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tolerance = 1e-9 * self.duration
        if t.ndim != 1 or not np.all(np.isfinite(t)) or np.any(t < -tolerance) or np.any(
                t > self.duration + tolerance):
            raise InvalidInputError(
                f't: expected finite times of shape (N,) in [0, {self.duration:.9g}] s, got '
                f'shape {t.shape}, range [{np.min(t) if t.size else 0.0:.9g}, '
                f'{np.max(t) if t.size else 0.0:.9g}]')
        factor = self.time_scale
        s, v, a, j = self.law.state(np.clip(t, 0.0, self.duration) / factor)
        return s, v / factor, a / factor ** 2, j / factor ** 3

    def evaluate(self, t):
        """
        Return the TCP motion at times ``t``.

        Parameters
        ----------
        t : array_like
            Times [s], shape (N,), within [0, duration].

        Returns
        -------
        tuple of numpy.ndarray
            Position [m], velocity [m/s], acceleration [m/s**2] and jerk
            [m/s**3], each of shape (N, 3), base frame. At T1 and T2 the
            acceleration steps (the curvature does); there the line's side is
            returned.

        """
        s, v, a, j = self.path_state(t)
        return _cartesian(self.path, s, v, a, j)

    def metrics(self, sample_period=CHECK_PERIOD):
        """
        Return the motion's numbers, sampled every ``sample_period``.

        Parameters
        ----------
        sample_period : float
            Time between samples [s], in (0, 0.1]; longer where the motion
            would need more than ``METRICS_SAMPLES`` samples.

        Returns
        -------
        dict
            ``duration`` [s], ``segment_durations`` (list of 3) [s],
            ``peak_speed`` [m/s], ``peak_accel`` [m/s**2], ``peak_jerk``
            [m/s**3] (the steps at T1/T2 are not jerk), ``accel_jump_T1`` and
            ``accel_jump_T2`` [m/s**2]; plain floats.

        """
        period = require_range('sample_period', sample_period, 0.0, 0.1, low_open=True,
                               unit='s')
        period = max(period, self.duration / METRICS_SAMPLES)
        speed, accel, jerk = _norms(self, _check_times(self, period))[1:]
        return {'duration': float(self.duration),
                'segment_durations': [float(value) for value in self.segment_durations],
                'peak_speed': float(speed.max()), 'peak_accel': float(accel.max()),
                'peak_jerk': float(jerk.max()), 'accel_jump_T1': float(self.accel_jump_T1),
                'accel_jump_T2': float(self.accel_jump_T2)}

    def jerk_steps(self):
        """
        Return the times [s] (K,) and sizes [m/s**3] (K,) of the steps of the TCP jerk.

        The jerk steps where the law's third derivative does (its piece bounds)
        and where the path's curvature rate does (T1, T2 and, with a G2 join,
        where the transitions meet the ellipse); the size is the norm of the
        difference of the one-sided jerk vectors.
        """
        law_times = getattr(self.law, 'times', None)
        candidates = [] if law_times is None else [law_times[1:-1] * self.time_scale]
        path = self.path
        if path.bend is not None:
            bend = path.bend
            marks = list(path.segment_ends[1:3])
            if path.join == 'g2':
                marks += list(path.segment_ends[1] + bend.s_from_t(
                    np.array([math.pi - bend.span_1, bend.span_2])))
            t = _sample_times(self.duration, CHECK_PERIOD)
            candidates.append(np.interp(marks, self.path_state(t)[0], t))
        times = np.unique(np.concatenate(candidates)) if candidates else np.zeros(0)
        times = times[(times > 0.0) & (times < self.duration)]
        epsilon = 1e-9 * self.duration
        before = self.evaluate(np.maximum(times - epsilon, 0.0))[3]
        after = self.evaluate(np.minimum(times + epsilon, self.duration))[3]
        return times, np.linalg.norm(after - before, axis=1)

    def scaled(self, factor):
        """
        Return the same motion slowed down uniformly in time.

        Parameters
        ----------
        factor : float
            Time-scaling factor, >= 1: durations x factor, velocities / factor,
            accelerations / factor**2, jerks / factor**3.

        Returns
        -------
        TimedMotion

        """
        factor = require_range('factor', factor, 1.0, 1e6)
        return replace(self, duration=self.duration * factor,
                       segment_durations=self.segment_durations * factor,
                       accel_jump_T1=self.accel_jump_T1 / factor ** 2,
                       accel_jump_T2=self.accel_jump_T2 / factor ** 2,
                       time_scale=self.time_scale * factor,
                       node_period=None if self.node_period is None
                       else self.node_period * factor)


def _cartesian(path, s, v, a, j):
    """Return position, velocity, acceleration and jerk (N, 3) from the path state."""
    samples = path.evaluate(s)
    tangent, curvature, rate = samples.tangent, samples.curvature, samples.curvature_rate
    return (samples.position, v[:, None] * tangent,
            a[:, None] * tangent + (v * v)[:, None] * curvature,
            j[:, None] * tangent + (3.0 * v * a)[:, None] * curvature
            + (v ** 3)[:, None] * rate)


def _sample_times(duration, period):
    """Return times from 0 to ``duration`` at most ``period`` apart, ends included."""
    return np.linspace(0.0, duration, int(math.ceil(duration / period)) + 1)


def _check_times(motion, period):
    """
    Return sample times of ``motion`` for its peaks: a grid plus both sides of every piece bound.

    Between the bounds of its constant-jerk pieces the motion is smooth, and the
    largest jerk (often the largest acceleration) sits at a bound: the grid
    alone would miss it by up to its period.
    """
    law_times = getattr(motion.law, 'times', None)
    grid = _sample_times(motion.duration, period)
    if law_times is None:
        return grid
    bounds = law_times[1:-1] * motion.time_scale
    # Just off the bound on both sides: at the bound itself the law is the next piece's
    # while the path may still be the previous segment's (at T1, T2).
    epsilon = 1e-9 * motion.duration
    return np.sort(np.concatenate((grid, np.maximum(bounds - epsilon, 0.0),
                                   np.minimum(bounds + epsilon, motion.duration))))


def _norms(motion, t):
    """Return (s', |velocity|, |acceleration|, |jerk|) of ``motion`` at ``t``, each (N,)."""
    s, v, a, j = motion.path_state(t)
    _, velocity, acceleration, jerk = _cartesian(motion.path, s, v, a, j)
    return (s, np.linalg.norm(velocity, axis=1), np.linalg.norm(acceleration, axis=1),
            np.linalg.norm(jerk, axis=1))


def _within_limits(motion, limits, speed_cap):
    """
    Return ``motion``, slowed down uniformly if sampling finds a limit broken.

    A construction that breaks a limit has missed something sharp (a bend
    tighter than its tables): the factor is then measured on a grid
    ``SAFETY_REFINE`` times finer and given ``SAFETY_SLACK`` on top, for what
    falls between even those samples.
    """
    period = max(SAFETY_CHECK_PERIOD, motion.duration / SAFETY_CHECK_SAMPLES)
    factor = _excess(motion, limits, speed_cap, period)
    if factor <= 1.0:
        return motion
    factor = max(factor, _excess(motion, limits, speed_cap, period / SAFETY_REFINE))
    return motion.scaled(factor * (1.0 + SAFETY_SLACK))


def _excess(motion, limits, speed_cap, period):
    """Return the uniform slow-down that brings the sampled motion within the limits (>= 0)."""
    s, speed, accel, jerk = _norms(motion, _check_times(motion, period))
    factor = max(float(speed.max()) / limits.max_speed,
                 math.sqrt(float(accel.max()) / limits.max_accel),
                 float(jerk.max() / limits.max_jerk) ** (1.0 / 3.0))
    if speed_cap is not None:
        factor = max(factor, float(np.max(speed / _cap_values(speed_cap, s))))
    return factor


def _cap_values(speed_cap, s):
    """Call the speed cap on path lengths ``s`` (N,) and check the answer."""
    values = np.asarray(speed_cap(s), dtype=float)
    if values.shape != s.shape or not np.all(values > 0.0) or not np.all(np.isfinite(values)):
        raise InvalidInputError(
            f'speed_cap: expected positive finite speeds of shape {s.shape} [m/s], got '
            f'shape {values.shape}, minimum {np.min(values) if values.size else None}')
    return values


# -- entry point -----------------------------------------------------------------------------

def time_motion(path, limits=None, profile='time_optimal', r=0.77, speed_cap=None):
    """
    Time a pick-and-place path.

    Parameters
    ----------
    path : PickPlacePath
        The path (:func:`~ellipath_ros.core.geometry.plan_path`).
    limits : CartesianLimits, optional
        Defaults when omitted.
    profile : str
        ``'time_optimal'`` (default) or ``'curvature'`` (the paper's).
    r : float
        The paper's proportionality coefficient [rad/m], > 0 (curvature only).
    speed_cap : callable, optional
        ``speed_cap(s)`` -> largest s' [m/s] at path lengths ``s`` (N,), an
        array of shape (N,), positive; e.g. from joint velocity limits.

    Returns
    -------
    TimedMotion

    Raises
    ------
    InvalidInputError
        Unknown profile, r <= 0, a bad path, limits or speed cap.
    LimitError
        No motion within the limits was found (not expected with positive
        limits; the slow fallback below always finds one).

    Notes
    -----
    ``time_optimal``: the vertical segments are straight, so Ruckig times them
    exactly (from rest to the arc's entry state, from its exit state to rest).
    Entry and exit speeds are the largest the acceleration step, the
    curvature, the cap and the clearance allow, with s'' = 0 there. On the
    arc, a scan integrates s''' in steps of ``SCAN_STEP`` (shorter on tight
    curvature) forwards from T1 and, mirrored, backwards from T2. Each step
    takes the largest jerk legal at both of its ends, aims s'' at the largest
    value the state allows (acceleration norm, and the normal jerk
    3 kappa v s'' + kappa_s v**3 within a share of the budget, negative where
    the curvature tightens too fast) and levels s'' off below the speed limit
    and the cap, which is read as stairs so that two scans cruising on one
    stair meet. Where the aim falls faster than the jerk can follow, the scan
    backs up and aims lower there. The slower scan advances until the two
    speed curves cross; one constant-jerk piece, solved for continuity of s,
    s', s'' at both ends (Newton, then bracketing), joins them. Where they
    cannot meet (a speed valley inside the arc: a tight bend or a dip of the
    cap), the arc is split at the lowest ceiling and each part solved the
    same way; an end speed the arc cannot take comes down. If all that
    fails, a sure but slow construction (Ruckig pieces between knots, each
    with constant limits valid on its stretch) is used.

    """
    if not isinstance(path, PickPlacePath):
        raise InvalidInputError(f'path: expected a PickPlacePath, got {type(path).__name__}')
    limits = CartesianLimits() if limits is None else limits
    if not isinstance(limits, CartesianLimits):
        raise InvalidInputError(
            f'limits: expected a CartesianLimits, got {type(limits).__name__}')
    if profile not in PROFILES:
        raise InvalidInputError(
            f'profile: expected one of {", ".join(PROFILES)}, got {profile!r}')
    r = require_range('r', r, 0.0, math.inf, low_open=True, unit='rad/m')
    if speed_cap is not None and not callable(speed_cap):
        raise InvalidInputError(
            f'speed_cap: expected a callable or None, got {type(speed_cap).__name__}')
    if profile == 'curvature':
        if path.join != 'paper':
            raise InvalidInputError(
                f'join: expected paper with the curvature profile (its node rule is the '
                f"paper's, on the ellipse), got {path.join!r}")
        motion = _curvature_motion(path, limits, r, speed_cap)
    else:
        motion = _optimal_motion(path, limits, speed_cap)
    return _within_limits(motion, limits, speed_cap)


# -- Ruckig on one degree of freedom -----------------------------------------------------------

def _ruckig_rows(start, target, speed, accel, jerk):
    """
    Return the time-optimal 1-DoF pieces from ``start`` to ``target`` (s, s', s''), or None.

    None when Ruckig finds nothing or the motion is not monotone (it would
    overshoot and come back: the distance is too short for the states).
    """
    data = InputParameter(1)
    data.current_position, data.current_velocity, data.current_acceleration = (
        [value] for value in start)
    data.target_position, data.target_velocity, data.target_acceleration = (
        [value] for value in target)
    data.max_velocity, data.max_acceleration, data.max_jerk = [speed], [accel], [jerk]
    trajectory = Trajectory(1)
    try:
        if Ruckig(1).calculate(data, trajectory) != Result.Working:
            return None
    except RuckigError:
        # Ruckig refuses states beyond its limits (e.g. a target acceleration above them).
        return None
    profile = trajectory.profiles[0][0]
    rows = []
    brake = profile.brake
    for index in range(2):
        if brake.t[index] > 0.0:
            rows.append((brake.t[index], brake.p[index], brake.v[index], brake.a[index],
                         brake.j[index]))
    for index in range(7):
        if profile.t[index] > 0.0:
            rows.append((profile.t[index], profile.p[index], profile.v[index],
                         profile.a[index], profile.j[index]))
    for duration, _, v, a, j in rows:
        # Smallest speed on the piece: at its ends or where s'' = 0 inside it.
        ends = [v, v + a * duration + 0.5 * j * duration ** 2]
        if j != 0.0 and 0.0 < -a / j < duration:
            ends.append(v - 0.5 * a * a / j)
        if min(ends) < -1e-9:
            return None
    return rows


def _reach_speed(distance, accel, jerk):
    """Return the largest speed reachable from rest over ``distance`` ending at s'' = 0."""
    if distance <= 0.0:
        return 0.0
    # Without a constant-acceleration phase: distance = v sqrt(v / J).
    speed = (distance * math.sqrt(jerk)) ** (2.0 / 3.0)
    if speed <= accel * accel / jerk:
        return speed
    # With one: distance = v (v / A + A / J) / 2.
    ratio = accel / jerk
    return 0.5 * accel * (-ratio + math.sqrt(ratio * ratio + 8.0 * distance / accel))


def _line_rows(start, target, limits, speed_cap, s_from, s_to):
    """Return Ruckig pieces along a straight segment [s_from, s_to] (None if none fit)."""
    speed = limits.max_speed * SPEED_MARGIN
    if speed_cap is not None and s_to > s_from:
        speed = min(speed, SPEED_MARGIN * float(np.min(_cap_values(
            speed_cap, np.linspace(s_from, s_to, LIMIT_SAMPLES)))))
    return _ruckig_rows(start, target, speed, limits.max_accel * ACCEL_MARGIN,
                        limits.max_jerk * JERK_MARGIN)


def _rows_duration(rows):
    return float(sum(row[0] for row in rows))


def _vertical_motion(path, limits, speed_cap, profile):
    """Time a pure vertical move: one straight segment from rest to rest."""
    rows = _line_rows((0.0, 0.0, 0.0), (path.length, 0.0, 0.0), limits, speed_cap,
                      0.0, path.length)
    if rows is None:
        raise LimitError('vertical move: expected Ruckig to find a rest-to-rest motion, '
                         f'got none for {path.length:.6g} m')
    pieces = _PieceList()
    pieces.extend(rows)
    law = pieces.law()
    going_up = path.segment_lengths[0] > 0.0
    segments = [law.duration, 0.0, 0.0] if going_up else [0.0, 0.0, law.duration]
    return TimedMotion(path, profile, law.duration, np.array(segments), 0.0, 0.0, None, law)


# -- the paper's curvature profile ------------------------------------------------------------

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
        r <= 0, or so small that the list would exceed ``MAX_NODES``.

    """
    r = require_range('r', r, 0.0, math.inf, low_open=True, unit='rad/m')
    # Node count ~ integral of dtheta / (r rho): refuse huge lists before building them.
    law = _CurvatureArcLaw(arc, 1.0, 0.0, arc.theta_T1, arc.theta_T2)
    estimate = law.duration / r
    if estimate > MAX_NODES:
        raise InvalidInputError(
            f'r: expected a value giving at most {MAX_NODES} nodes (r >= '
            f'{law.duration / MAX_NODES:.3g} rad/m for this arc), got {r!r} rad/m')
    a, b = arc.a, arc.b
    theta = arc.theta_T1
    nodes = [theta]
    while theta > arc.theta_T2:
        theta -= r * (a * a * math.sin(theta) ** 2 + b * b * math.cos(theta) ** 2) ** 1.5 / (
            a * b)
        nodes.append(theta)
    nodes[-1] = arc.theta_T2
    return np.array(nodes)


def _arc_cartesian_peaks(arc, theta):
    """Return |v|, |a|, |j| of the rule with K = 1 at ``theta`` (paper frame), each (N,)."""
    a, b = arc.a, arc.b
    ab = a * b
    sin, cos = np.sin(theta), np.cos(theta)
    sigma = np.sqrt(a * a * sin ** 2 + b * b * cos ** 2)
    sigma_1 = (a * a - b * b) * np.sin(2.0 * theta) / (2.0 * sigma)
    sigma_2 = ((a * a - b * b) * np.cos(2.0 * theta) - sigma_1 ** 2) / sigma
    rho = sigma ** 3 / ab
    rho_1 = 3.0 * sigma ** 2 * sigma_1 / ab
    rho_2 = (6.0 * sigma * sigma_1 ** 2 + 3.0 * sigma ** 2 * sigma_2) / ab
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
    a, b = arc.a, arc.b
    ab = a * b
    sigma = math.sqrt(a * a * math.sin(theta) ** 2 + b * b * math.cos(theta) ** 2)
    sigma_1 = (a * a - b * b) * math.sin(2.0 * theta) / (2.0 * sigma)
    return (float(arc.s_from_t(arc.t_from_theta(theta))), rate * sigma ** 4 / ab,
            -4.0 * rate ** 2 * sigma ** 6 * sigma_1 / ab ** 2)


def _constant_limits(path, s_from, s_to, speed, limits):
    """
    Return (s'' limit, s''' limit) that keep the true limits on [s_from, s_to] at s' <= speed.

    Conservative constants for a Ruckig piece along a curved stretch (worst
    curvature and curvature rate of the stretch, worst case of every term);
    None if there are none.
    """
    s = np.linspace(s_from, s_to, LIMIT_SAMPLES)
    bend = _bend_length(path)
    if bend is not None and s_from < bend < s_to:
        s = np.sort(np.append(s, bend))
    samples = path.evaluate(s)
    kappa = np.linalg.norm(samples.curvature, axis=1)
    normal = samples.curvature / np.maximum(kappa, 1e-300)[:, None]
    kappa = float(kappa.max())
    kappa_s = float(np.abs(np.einsum('ij,ij->i', samples.curvature_rate, normal)).max())
    accel, jerk = limits.max_accel * ACCEL_MARGIN, limits.max_jerk * JERK_MARGIN
    if kappa * speed * speed >= accel:
        return None
    tangential = math.sqrt(accel ** 2 - (kappa * speed * speed) ** 2)
    if kappa * speed > 0.0:
        tangential = min(tangential, (0.5 * jerk - kappa_s * speed ** 3) / (3.0 * kappa * speed))
    normal_jerk = kappa_s * speed ** 3 + 3.0 * kappa * speed * tangential
    if tangential <= 0.0 or normal_jerk >= jerk:
        return None
    rate = math.sqrt(jerk ** 2 - normal_jerk ** 2) - kappa ** 2 * speed ** 3
    return (tangential, rate) if rate > 0.0 else None


def _bend_length(path):
    """Return the path length [m] of the bend's tightest point, or None without an arc."""
    bend = path.bend
    if bend is None:
        return None
    return float(path.segment_lengths[0] + bend.s_from_t(bend.tightest_t))


def _curvature_motion(path, limits, r, speed_cap):
    """Build the paper's profile (module docstring): the rule on the arc, Ruckig elsewhere."""
    if path.arc is None:
        return _vertical_motion(path, limits, speed_cap, 'curvature')
    arc = path.arc
    nodes = curvature_nodes(arc, r)
    # The tightest point (theta = 0 mod pi) is sampled exactly.
    theta = np.linspace(arc.theta_T1, arc.theta_T2, _BASELINE_SAMPLES)
    theta = np.sort(np.append(theta, math.pi * math.ceil(arc.theta_T2 / math.pi)))[::-1]
    speed, accel, jerk = _arc_cartesian_peaks(arc, theta)
    rate = min(limits.max_speed * SPEED_MARGIN / speed.max(),
               math.sqrt(limits.max_accel * ACCEL_MARGIN / accel.max()),
               (limits.max_jerk * JERK_MARGIN / jerk.max()) ** (1.0 / 3.0))
    if speed_cap is not None:
        s = path.segment_lengths[0] + arc.s_from_t(arc.t_from_theta(theta))
        rate = min(rate, SPEED_MARGIN * float(np.min(_cap_values(speed_cap, s) / speed)))
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


def _pieces_law(rows, s_offset=0.0):
    pieces = _PieceList()
    pieces.extend(rows, s_offset)
    return pieces.law()


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
            nodes[_ramp_nodes(count)], arc.theta_T1 - math.pi * RAMP_FRACTIONS)))[::-1], True)
        if ramp_in is None:
            return None
        theta_start = ramp_in[0]
        arc_laws.append(_pieces_law(ramp_in[1], c1))
    if c2 <= 0.0 or ramps:
        ramp_out = _curvature_ramp(path, limits, rate, np.sort(np.concatenate((
            nodes[count - 1 - _ramp_nodes(count)], arc.theta_T2 + math.pi * RAMP_FRACTIONS))),
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
    (nodes near the end and points at ``RAMP_FRACTIONS`` of the arc), the one
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


# -- the time-optimal profile ------------------------------------------------------------------

class _NoMotion(Exception):
    """The scans found no motion for a stretch (the caller tries something slower)."""


class _EndTooFast(Exception):
    """The scan from T1 (``at_start``) or T2 gives up: that end's speed must come down."""

    def __init__(self, at_start):
        super().__init__()
        self.at_start = at_start


class _ArcTable:
    """Curvature kappa and dkappa/ds on a uniform grid along the arc, the speed cap per cell."""

    __slots__ = ('length', 'step', 'last', 'kappa', 'kappa_s', 'cap')

    def __init__(self, length, kappa, kappa_s, cap):
        # Lists, not arrays: the scans read single values, which lists serve faster.
        self.length = length
        self.step = length / (len(kappa) - 1)
        self.last = len(kappa) - 2
        self.kappa, self.kappa_s, self.cap = kappa, kappa_s, cap

    def backwards(self):
        """Return the table of the arc run from T2 to T1 (dkappa/ds changes sign)."""
        return _ArcTable(self.length, self.kappa[::-1], [-value for value in self.kappa_s[::-1]],
                         self.cap[::-1])

    def at(self, s):
        """Return (kappa, dkappa/ds, speed cap) at arc length ``s``."""
        x = s / self.step
        index = min(max(int(x), 0), self.last)
        fraction = x - index
        kappa, kappa_s, cap = self.kappa, self.kappa_s, self.cap
        return (kappa[index] + fraction * (kappa[index + 1] - kappa[index]),
                kappa_s[index] + fraction * (kappa_s[index + 1] - kappa_s[index]),
                cap[index])


class _Scan:
    """
    States (t, s, s', s'') of a greedy scan along the arc and the jerk of each step.

    ``t``, ``s``, ``v``, ``a`` have one entry per state, ``j`` one per step.
    ``status`` is 'live', 'end' (reached ``end``), 'speed' (the speed became
    too high for what lies ahead: the other scan covers it) or 'accel' (gave
    up after ``failures`` back-ups).
    """

    __slots__ = ('t', 's', 'v', 'a', 'j', 'end', 'status', 'failures')

    def __init__(self, s, v, a, end):
        self.t, self.s, self.v, self.a, self.j = [0.0], [s], [v], [a], []
        self.end, self.status, self.failures = end, 'live', 0

    def speed_at(self, s_query):
        """Return s' at ``s_query`` interpolated between states, or None outside the scan."""
        position = bisect_right(self.s, s_query)
        if position == 0 or position >= len(self.s):
            return None
        low, high = self.s[position - 1], self.s[position]
        x = (s_query - low) / (high - low) if high > low else 0.0
        return self.v[position - 1] + x * (self.v[position] - self.v[position - 1])

    def state(self, time):
        """Return (s, s', s'') at ``time`` (clamped to the scan)."""
        index = min(max(bisect_right(self.t, time) - 1, 0), max(len(self.j) - 1, 0))
        if not self.j:
            return self.s[0], self.v[0], self.a[0]
        x = time - self.t[index]
        v, a, j = self.v[index], self.a[index], self.j[index]
        return (self.s[index] + x * (v + x * (a / 2.0 + x * j / 6.0)),
                v + x * (a + x * j / 2.0), a + x * j)

    def time_at(self, s_query):
        """Return the time at which the scan reaches ``s_query`` (within its range)."""
        index = min(max(bisect_right(self.s, s_query) - 1, 0), max(len(self.j) - 1, 0))
        low, high = self.t[index], self.t[min(index + 1, len(self.t) - 1)]
        for _ in range(60):
            middle = 0.5 * (low + high)
            if self.state(middle)[0] < s_query:
                low = middle
            else:
                high = middle
        return 0.5 * (low + high)

    def rows(self, time):
        """Return the pieces from the start to ``time``."""
        rows = []
        for index, jerk in enumerate(self.j):
            if self.t[index] >= time:
                break
            rows.append((min(self.t[index + 1], time) - self.t[index], self.s[index],
                         self.v[index], self.a[index], jerk))
        return rows

    def reversed_rows(self, time, length):
        """Return the forward-time pieces of a backward scan from ``time`` back to its start."""
        rows = []
        index = min(max(bisect_right(self.t, time) - 1, 0), len(self.j) - 1)
        s, v, a = self.state(time)
        if time > self.t[index]:
            rows.append((time - self.t[index], length - s, v, -a, self.j[index]))
        for index in range(index - 1, -1, -1):
            rows.append((self.t[index + 1] - self.t[index], length - self.s[index + 1],
                         self.v[index + 1], -self.a[index + 1], self.j[index]))
        return rows


class _Scanner:
    """The greedy path-space scan along one direction of the arc (see :func:`time_motion`)."""

    def __init__(self, table, limits):
        self.table = table
        self.speed = limits.max_speed * SPEED_MARGIN
        self.accel = limits.max_accel * ACCEL_MARGIN
        self.jerk = limits.max_jerk * JERK_MARGIN
        self.factor = [1.0] * (len(table.kappa) + 1)

    def jerk_range(self, s, v, a):
        """Return the (lowest, highest) s''' keeping |jerk| <= limit at (s, v, a), or None."""
        kappa, kappa_s, _ = self.table.at(s)
        return self._jerk_range(kappa, kappa_s, v, a)

    def _jerk_range(self, kappa, kappa_s, v, a):
        # |jerk|**2 = (s''' - kappa**2 v**3)**2 + (kappa_s v**3 + 3 kappa v a)**2.
        v3 = v * v * v
        normal = kappa_s * v3 + 3.0 * kappa * v * a
        if abs(normal) >= self.jerk:
            return None
        room = math.sqrt(self.jerk ** 2 - normal * normal)
        return kappa * kappa * v3 - room, kappa * kappa * v3 + room

    def _target(self, s, v, kappa, kappa_s, cap):
        """
        Return the largest s'' to aim at in state (s, v), or None if v is too high there.

        Below the acceleration norm, and such that the normal jerk
        3 kappa v s'' + kappa_s v**3 leaves a share of the jerk budget for
        changing s'' (with s''' = 0 feasible: the tangential part of p''' v**3
        is -kappa**2 v**3). Negative where the curvature tightens too fast for
        the speed: the scan then slows down. A back-up lowers it.
        """
        if v <= 0.0 or v > cap * (1.0 + 1e-9):
            return None
        normal = kappa * v * v
        centripetal = kappa * kappa * v ** 3
        if normal >= self.accel or centripetal >= self.jerk:
            return None
        tangential = math.sqrt(self.accel ** 2 - normal * normal)
        target, lowest = tangential, -tangential
        if kappa * v > 0.0:
            share = NORMAL_JERK_SHARE * math.sqrt(self.jerk ** 2 - centripetal ** 2)
            target = min(target, (share - kappa_s * v ** 3) / (3.0 * kappa * v))
            lowest = max(lowest, (-share - kappa_s * v ** 3) / (3.0 * kappa * v))
        factor = self.factor[min(max(int(s / self.table.step), 0), len(self.factor) - 1)]
        target = factor * target if target > 0.0 else target - (1.0 - factor) * self.accel
        return target if target >= lowest else None

    def step(self, s, v, a):
        """Take one scan step from state (s, v, a): (h, s, v, a, jerk) or a failure string."""
        at = self.table.at
        kappa, kappa_s, cap = at(s)
        bounds = self._jerk_range(kappa, kappa_s, v, a)
        speed = min(self.speed, cap)
        if bounds is None or v > speed * (1.0 + 1e-9) or (a < 0.0 and v < MIN_SCAN_SPEED):
            return 'speed'
        lowest, highest = bounds
        h = SCAN_STEP if kappa <= SCAN_KAPPA else SCAN_STEP_SHORT
        if v * abs(kappa_s) * h > SCAN_KAPPA_CHANGE * kappa:
            # The curvature changes fast here (a needle-sharp bend): shorter steps.
            h = max(SCAN_KAPPA_CHANGE * kappa / (v * abs(kappa_s)), SCAN_STEP_MIN)
        # Levelling off ramps s'' down with a share of the jerk the state leaves for it.
        level = LEVEL_OFF_JERK * max(-lowest, 1e-3 * self.jerk)
        # Level off (and cruise) at the lowest speed limit until where the levelling off
        # would end.
        reach = v * max(a, LEVEL_REACH * self.accel) / level
        goal = min(speed, at(s + 0.5 * reach)[2], at(s + reach)[2])
        if a <= 1e-12 and v >= goal * (1.0 - 1e-9):
            jerk, a = 0.0, 0.0
            # Cruising changes nothing but the place: up to half a table cell per step.
            h = max(h, 0.5 * self.table.step / v)
        elif a > 0.0 and v + a * a / (2.0 * level) >= goal * (1.0 - 1e-12):
            jerk, h = self._level_off(v, a, goal, h, level)
        else:
            jerk = highest
            for _ in range(12):
                s1 = s + h * (v + h * (a / 2.0 + h * jerk / 6.0))
                v1 = v + h * (a + h * jerk / 2.0)
                target = self._target(s1, v1, *at(s1))
                if target is None:
                    # Too fast at the step's end: try less jerk (down to the lowest).
                    if jerk <= lowest + 1e-9:
                        return 'speed'
                    jerk = 0.5 * (jerk + lowest)
                    continue
                if a + jerk * h <= target + 1e-12:
                    break
                jerk = (target - a) / h
            a1, v1 = a + jerk * h, v + h * (a + h * jerk / 2.0)
            if a1 > 0.0 and v1 + a1 * a1 / (2.0 * level) > goal:
                h = self._until_level_off(v, a, jerk, h, goal, level)
                if h <= 1e-12:
                    jerk, h = self._level_off(v, a, goal, SCAN_STEP_SHORT, level)
            elif a > 0.0 > a1 and v - a * a / (2.0 * jerk) > goal:
                # s'' passes 0 inside the step: its speed peak must stay below the limit too.
                jerk, h = self._level_off(v, a, goal, h, level)
        if jerk >= lowest - 1e-9:
            jerk = self._end_feasible(s, v, a, jerk, lowest, h)
            if jerk is not None:
                return (h, s + h * (v + h * (a / 2.0 + h * jerk / 6.0)),
                        v + h * (a + h * jerk / 2.0), a + h * jerk, jerk)
        # Not accelerating, the speed itself is too high for what follows.
        return 'accel' if a > 1e-9 else 'speed'

    def _level_off(self, v, a, speed, h, level):
        """Return (jerk, step): constant jerk bringing s'' to 0 exactly at s' = speed."""
        gap = speed - v
        jerk = -level if gap <= 0.0 else max(-a * a / (2.0 * gap), -self.jerk)
        return jerk, min(h, a / -jerk)

    def _until_level_off(self, v, a, jerk, h, speed, level):
        """Return the time within the step at which v + a**2/(2 level) reaches ``speed``."""
        low, high = 0.0, h
        for _ in range(40):
            x = 0.5 * (low + high)
            a1 = a + jerk * x
            if v + x * (a + x * jerk / 2.0) + a1 * a1 / (2.0 * level) > speed:
                high = x
            else:
                low = x
        return low

    def _end_feasible(self, s, v, a, jerk, lowest, h):
        """Return ``jerk``, or the largest one in [lowest, jerk] legal at the step's end."""
        def legal(value):
            bounds = self.jerk_range(s + h * (v + h * (a / 2.0 + h * value / 6.0)),
                                     v + h * (a + h * value / 2.0), a + h * value)
            return bounds is not None and bounds[0] - 1e-9 <= value <= bounds[1] + 1e-9
        if legal(jerk):
            return jerk
        low, high, best = lowest, jerk, None
        for _ in range(12):
            middle = 0.5 * (low + high)
            if legal(middle):
                best, low = middle, middle
            else:
                high = middle
        return best

    def advance(self, scan, back_up=True):
        """
        Take one step of ``scan``; return False once it cannot go on (see its status).

        Where the acceleration bound falls faster than the jerk can follow,
        the scan backs up ``BACK_UP_STEPS`` and lowers its acceleration target
        over the stretch (lower again on repeated trouble).
        """
        if scan.status != 'live':
            return False
        if scan.s[-1] >= scan.end:
            scan.status = 'end'
            return False
        result = self.step(scan.s[-1], scan.v[-1], scan.a[-1])
        if not isinstance(result, str):
            h, s1, v1, a1, jerk = result
            scan.t.append(scan.t[-1] + h)
            scan.s.append(s1)
            scan.v.append(v1)
            scan.a.append(a1)
            scan.j.append(jerk)
            return True
        if result == 'speed' or scan.failures >= BACK_UP_LIMIT or not back_up:
            scan.status = result
            return False
        scan.failures += 1
        last = len(scan.s) - 1
        first = max(0, last - BACK_UP_STEPS)
        step = self.table.step
        bins = range(max(int(scan.s[first] / step), 0),
                     min(int((scan.s[last] + BACK_UP_AHEAD) / step) + 1, len(self.factor)))
        lowered = BACK_UP_FACTOR * min(self.factor[index] for index in bins)
        for index in bins:
            self.factor[index] = min(self.factor[index], lowered)
        for values in (scan.t, scan.s, scan.v, scan.a):
            del values[first + 1:]
        del scan.j[first:]
        return True


class _ArcPlanner:
    """The time-optimal construction on the arc: scans, joins and speed valleys."""

    def __init__(self, path, limits, speed_cap):
        bend = path.bend
        self.path, self.limits = path, limits
        self.length = float(path.segment_lengths[1])
        # Curvature on a fine grid of the curve parameter, resampled uniformly in s.
        # Cells no longer than the smallest radius of curvature (the arc may be a needle).
        intervals = int(min(TABLE_INTERVALS_MAX, max(TABLE_INTERVALS, 2 ** math.ceil(
            math.log2(self.length / bend.min_radius)))))
        t = np.linspace(math.pi, 0.0, 2 * intervals + 1)
        sigma = bend.speed(t)
        # Arc length by Simpson on pairs of intervals, scaled to the exact length.
        pairs = (sigma[:-2:2] + 4.0 * sigma[1:-1:2] + sigma[2::2]) * (math.pi / len(sigma))
        s_t = np.interp(np.arange(sigma.size), np.arange(0, sigma.size, 2),
                        np.concatenate(([0.0], np.cumsum(pairs) / 3.0 * 2.0)))
        s_t *= self.length / s_t[-1]
        grid = np.linspace(0.0, self.length, intervals + 1)
        kappa_t, kappa_s_t = bend.curvature_and_rate(t)
        # The bend never turns the other way; a G2 end's 0 may round to -1e-14.
        kappa = np.maximum(np.interp(grid, s_t, kappa_t), 0.0)
        kappa_s = np.interp(grid, s_t, kappa_s_t)
        # The speed cap as stairs of CAP_STAIR cells, each at the lowest value it spans: the
        # scans level off on a stair and cruise, and two scans cruising on one stair meet.
        cells = np.full(intervals, math.inf)
        if speed_cap is not None:
            values = SPEED_MARGIN * _cap_values(speed_cap, path.segment_lengths[0] + grid)
            lowest = np.minimum(values[:-1], values[1:]).reshape(-1, CAP_STAIR).min(axis=1)
            cells = np.repeat(lowest, CAP_STAIR)
        self.grid = grid
        table = _ArcTable(self.length, kappa.tolist(), kappa_s.tolist(), cells.tolist())
        self.forward = _Scanner(table, limits)
        self.backward = _Scanner(table.backwards(), limits)
        # The ceiling places the speed valleys and their speeds.
        cap = np.minimum(np.concatenate((cells[:1], cells)), np.concatenate((cells, cells[-1:])))
        self.ceiling = self._cruise_speed(kappa, kappa_s, cap, CEILING_SHARE)
        # A G2 join's ends have curvature 0 exactly (the table holds rounding there).
        self.kappa_end = ((0.0, 0.0) if path.join == 'g2'
                          else (float(kappa[0]), float(kappa[-1])))
        self.hills = 0

    def _cruise_speed(self, kappa, kappa_s, cap, share):
        """Return the speed at which s'' = 0 uses ``share`` of the accel and jerk limits."""
        limits = self.limits
        accel, jerk = limits.max_accel * ACCEL_MARGIN, limits.max_jerk * JERK_MARGIN
        with np.errstate(divide='ignore'):
            return np.minimum.reduce([
                np.full(kappa.shape, limits.max_speed * SPEED_MARGIN), cap,
                np.sqrt(share * accel / kappa),
                (share * jerk / np.hypot(kappa ** 2, kappa_s)) ** (1.0 / 3.0)])

    def end_speed(self, clearance, at_start, speed_cap):
        """Return the speed aimed at at T1 (``at_start``) or T2, with s'' = 0 there."""
        limits = self.limits
        index = 0 if at_start else -1
        # A G2 join has no curvature at T1/T2, hence no acceleration step to bound.
        step_speed = (math.inf if self.kappa_end[index] <= 0.0 else
                      math.sqrt(limits.max_accel_jump / self.kappa_end[index]) * (1.0 - 1e-3))
        speed = min(float(self.ceiling[index]), step_speed,
                    _reach_speed(clearance, limits.max_accel * ACCEL_MARGIN,
                                 limits.max_jerk * JERK_MARGIN) * (1.0 - 1e-3))
        if speed_cap is not None and clearance > 0.0:
            start = 0.0 if at_start else self.path.length - clearance
            speed = min(speed, SPEED_MARGIN * float(np.min(_cap_values(
                speed_cap, np.linspace(start, start + clearance, LIMIT_SAMPLES)))))
        return speed

    def solve(self, v_in, v_out):
        """
        Return (arc rows, entry (s', s''), exit (s', s'')) from T1 to T2.

        An end speed the arc cannot take (the curvature grows too fast just
        inside it) comes down by ``END_RETRY_FACTOR`` until it can.
        """
        for _ in range(END_TRIES):
            try:
                return self._hill(0.0, (v_in, 0.0), self.length, (v_out, 0.0), True, True, 0)
            except _EndTooFast as trouble:
                if trouble.at_start:
                    v_in *= END_RETRY_FACTOR
                else:
                    v_out *= END_RETRY_FACTOR
        raise _NoMotion()

    def _hill(self, s_a, state_a, s_b, state_b, free_a, free_b, depth):
        """
        Solve [s_a, s_b] from state_a to state_b ((s', s'') each).

        A free end (T1, T2) may end at a lower state when the other scan
        never comes down to it (the clearance then adapts); a fixed end (a
        speed valley) may not.
        """
        self.hills += 1
        if self.hills > HILL_BUDGET:
            raise _NoMotion()
        length = self.length
        forward = _Scan(s_a, state_a[0], state_a[1], s_b)
        backward = _Scan(length - s_b, state_b[0], -state_b[1], length - s_a)
        self._scan_both(forward, backward)
        joined = self._join(forward, backward)
        if joined is not None:
            return joined, state_a, state_b

        if forward.status == 'end' and free_b:
            time = forward.time_at(s_b)
            end = forward.state(time)
            if end[1] <= state_b[0] * (1.0 + 1e-9):
                return forward.rows(time), state_a, end[1:]
        if backward.status == 'end' and free_a:
            time = backward.time_at(length - s_a)
            end = backward.state(time)
            if end[1] <= state_a[0] * (1.0 + 1e-9):
                return backward.reversed_rows(time, length), (end[1], -end[2]), state_b
        index = self._valley_index(forward, backward, s_a, s_b)
        if index is not None and depth < VALLEY_DEPTH:
            return self._split(index, s_a, state_a, s_b, state_b, free_a, free_b, depth)
        # No valley in between: a scan from a free end that gives up started too fast.
        failed_a = forward.status != 'end' and free_a
        failed_b = backward.status != 'end' and free_b
        if failed_a and failed_b:
            failed_a = forward.s[-1] - s_a < backward.s[-1] - (length - s_b)
            failed_b = not failed_a
        if failed_a or failed_b:
            raise _EndTooFast(failed_a)
        raise _NoMotion()

    def _valley_index(self, forward, backward, s_a, s_b):
        """
        Return the grid index of the lowest ceiling between where the scans stopped, or None.

        Only a true valley counts: lower than the ceiling at both ends of the
        stretch searched (which reaches ``VALLEY_REACH`` beyond the scans' ends).
        """
        grid_step = self.grid[1]
        margin = 4 * grid_step
        ends = sorted((forward.s[-1], self.length - backward.s[-1]))
        low = int(max(ends[0] - VALLEY_REACH, s_a + margin) / grid_step)
        high = int(min(ends[1] + VALLEY_REACH, s_b - margin) / grid_step) + 1
        if high - low < 3:
            return None
        index = low + int(np.argmin(self.ceiling[low:high]))
        lowest = self.ceiling[index]
        if lowest < self.ceiling[low] * (1.0 - 1e-9) and lowest < self.ceiling[high - 1] * (
                1.0 - 1e-9):
            return index
        return None

    def _split(self, index, s_a, state_a, s_b, state_b, free_a, free_b, depth):
        """Solve [s_a, s_b] as two parts meeting at rest acceleration in valley ``index``."""
        s_v = float(self.grid[index])
        for attempt in range(VALLEY_TRIES):
            valley = (float(self.ceiling[index]) * VALLEY_SHARE * VALLEY_RETRY_FACTOR ** attempt,
                      0.0)
            try:
                left, entry, _ = self._hill(s_a, state_a, s_v, valley, free_a, False, depth + 1)
                right, _, exit_state = self._hill(s_v, valley, s_b, state_b, False, free_b,
                                                  depth + 1)
            except _NoMotion:
                continue
            return left + right, entry, exit_state
        raise _NoMotion()

    def _scan_both(self, forward, backward):
        """
        Advance the slower of the two scans until the two speed curves cross.

        Both scans speed up away from their start, so the crossing lies
        where the slower one catches up; neither needs to run past it.
        """
        length = self.length
        while forward.status == 'live' or backward.status == 'live':
            if forward.status == 'live' and (backward.status != 'live'
                                             or forward.v[-1] <= backward.v[-1]):
                if self.forward.advance(forward):
                    other = backward.speed_at(length - forward.s[-1])
                    if other is not None and forward.v[-1] >= other * (1.0 - 1e-12):
                        break
            elif self.backward.advance(backward):
                other = forward.speed_at(length - backward.s[-1])
                if other is not None and backward.v[-1] >= other * (1.0 - 1e-12):
                    break
        # Room on both sides of the crossing for the joining piece (no backing up past it).
        for _ in range(JOIN_ROOM_STEPS):
            self.forward.advance(forward, back_up=False)
            self.backward.advance(backward, back_up=False)

    def _join(self, forward, backward):
        """
        Return the rows forward scan -> one constant-jerk piece -> backward scan, or None.

        The piece starts at time x of the forward scan, ends at time y of the
        backward one and has jerk j: s, s', s'' must match at both ends,
        three equations in x, y and the piece's duration (see
        :meth:`_solve_join`). Where both scans cruise at the same speed, they
        are simply switched.
        """
        length = self.length
        crossing = self._crossing(forward, backward)
        if crossing is None:
            return None
        index, cruising = crossing
        if cruising:
            s_join = forward.s[index]
            y = backward.time_at(length - s_join)
            return forward.rows(forward.t[index]) + backward.reversed_rows(y, length)
        x_c = forward.t[index]
        y_c = backward.time_at(length - forward.s[index])
        a_f = forward.state(x_c)[2]
        a_b = -backward.state(y_c)[2]
        bounds = self.forward.jerk_range(forward.s[index], forward.v[index], a_f)
        if bounds is None:
            return None
        jerk = 0.99 * (bounds[0] if a_b < a_f else bounds[1])
        for _ in range(5):
            solution = self._solve_join(forward, backward, x_c, y_c, jerk)
            if solution is None:
                return None
            x, y, duration = solution
            worst = self._piece_check(forward.state(x), duration, jerk)
            if worst is None:
                return None
            if worst == jerk:
                s, v, a = forward.state(x)
                return (forward.rows(x) + [(duration, s, v, a, jerk)]
                        + backward.reversed_rows(y, length))
            jerk = 0.99 * worst
        return None

    def _crossing(self, forward, backward):
        """Return (forward index, both cruising) where the forward scan first tops the backward."""
        length = self.length
        sigma = backward.s
        previous = None
        for index in range(len(forward.s)):
            s = forward.s[index]
            position = bisect_right(sigma, length - s)
            if position == 0 or position >= len(sigma):
                continue
            x = (length - s - sigma[position - 1]) / (sigma[position] - sigma[position - 1])
            v_b = backward.v[position - 1] + x * (backward.v[position] - backward.v[position - 1])
            difference = forward.v[index] - v_b
            if (abs(difference) <= 1e-9 * v_b and index < len(forward.j)
                    and forward.j[index] == 0.0 and forward.a[index] == 0.0
                    and backward.a[position] == 0.0 and backward.a[position - 1] == 0.0):
                return index, True
            if difference > 1e-12 and previous is not None:
                return index, False
            previous = difference
        return None

    def _solve_join(self, forward, backward, x, y, jerk):
        """Solve the join for (x, y, duration) near the crossing (x, y); None if it fails."""
        length = self.length
        x_max, y_max = forward.t[-1], backward.t[-1]

        def residual(x, y):
            s_f, v_f, a_f = forward.state(x)
            s_b, v_b, a_b = backward.state(y)
            s_b, a_b = length - s_b, -a_b
            tau = (a_b - a_f) / jerk
            return (v_f + tau * (a_f + tau * jerk / 2.0) - v_b,
                    s_f + tau * (v_f + tau * (a_f / 2.0 + tau * jerk / 6.0)) - s_b, tau)

        def accept(x, y):
            tau = residual(x, y)[2]
            return (x, y, tau) if tau >= 0.0 else None

        x_c = x
        tau0 = max(residual(x, y)[2], 0.0)
        x, y = min(max(x - tau0 / 2.0, 0.0), x_max), min(max(y - tau0 / 2.0, 0.0), y_max)
        delta = 1e-7
        for _ in range(40):
            e_v, e_s, tau = residual(x, y)
            if abs(e_v) < 1e-10 and abs(e_s) < 1e-12:
                return accept(x, y)
            dv_x, ds_x, _ = residual(x + delta, y)
            dv_y, ds_y, _ = residual(x, y + delta)
            j11, j12 = (dv_x - e_v) / delta, (dv_y - e_v) / delta
            j21, j22 = (ds_x - e_s) / delta, (ds_y - e_s) / delta
            det = j11 * j22 - j12 * j21
            if det == 0.0:
                return None
            step_x = (j22 * e_v - j12 * e_s) / det
            step_y = (j11 * e_s - j21 * e_v) / det
            # Damped: a few milliseconds at most per iteration.
            scale = min(1.0, 0.005 / max(abs(step_x), abs(step_y), 1e-300))
            x = min(max(x - scale * step_x, 0.0), x_max)
            y = min(max(y - scale * step_y, 0.0), y_max)

        # Newton stalls where a scan has kinks (levelling off, cruising): bracket instead,
        # y for s continuity at each x, then x for s' continuity.
        def y_for(x):
            y = _bracket_root(lambda y: residual(x, y)[1], 0.0, y_max, 1e-13)
            return None if y is None else (y, residual(x, y)[0])

        low, step = x_c, 0.002
        end = y_for(x_c)
        if end is None:
            return None
        while True:
            low = max(low - step, 0.0)
            start = y_for(low)
            if start is not None and start[1] * end[1] <= 0.0:
                break
            if low <= 0.0:
                return None
            step *= 2.0
        x = _bracket_root(lambda x: (y_for(x) or (0.0, math.nan))[1], low, x_c, 1e-11)
        found = None if x is None else y_for(x)
        return None if found is None else accept(x, found[0])

    def _piece_check(self, start, duration, jerk):
        """
        Check a constant-jerk piece from ``start`` against the limits at 9 points.

        Returns ``jerk`` if it is legal all along, the most aggressive legal
        value otherwise (same sign, smaller), or None if no jerk can serve.
        """
        s, v, a = start
        scanner = self.forward
        worst = jerk
        for x in np.linspace(0.0, duration, 9):
            s1 = s + x * (v + x * (a / 2.0 + x * jerk / 6.0))
            v1, a1 = v + x * (a + x * jerk / 2.0), a + x * jerk
            kappa, _, cap = scanner.table.at(s1)
            bounds = scanner.jerk_range(s1, v1, a1)
            if (bounds is None or v1 < -1e-9 or v1 > min(cap, scanner.speed) * (1.0 + 1e-9)
                    or a1 * a1 + (kappa * v1 * v1) ** 2 > scanner.accel ** 2 * (1.0 + 1e-6)):
                return None
            worst = max(worst, bounds[0]) if jerk < 0.0 else min(worst, bounds[1])
        return worst if worst * jerk > 0.0 else None

    def fallback(self, v_in, v_out):
        """
        Return (rows, entry, exit) of a slower but sure motion along the arc.

        Ruckig pieces between ``FALLBACK_PIECES`` + 1 knots, at rest
        acceleration at each knot, with constant limits that hold on the
        piece's stretch (:func:`_constant_limits`); knot speeds start at half
        the ceiling around them and come down where a piece does not fit.
        """
        knots = np.linspace(0.0, self.length, FALLBACK_PIECES + 1)
        cells = np.minimum((knots / self.grid[1]).astype(int), self.grid.size - 1)
        speeds = [0.5 * float(self.ceiling[cells[max(index - 1, 0)]:
                                           cells[min(index + 1, FALLBACK_PIECES)] + 1].min())
                  for index in range(FALLBACK_PIECES + 1)]
        speeds[0], speeds[-1] = min(speeds[0], v_in), min(speeds[-1], v_out)
        offset = float(self.path.segment_lengths[0])
        pieces = [None] * FALLBACK_PIECES
        index, budget = 0, 20 * FALLBACK_PIECES
        while index < FALLBACK_PIECES:
            budget -= 1
            if budget < 0:
                raise LimitError('time-optimal profile: expected a motion along the arc within '
                                 'the limits, got none')
            top = max(speeds[index], speeds[index + 1])
            bounds = _constant_limits(self.path, offset + knots[index],
                                      offset + knots[index + 1], top, self.limits)
            pieces[index] = None if bounds is None else _ruckig_rows(
                (knots[index], speeds[index], 0.0), (knots[index + 1], speeds[index + 1], 0.0),
                top, *bounds)
            if pieces[index] is not None:
                index += 1
                continue
            # Slow the faster end of the piece; redo the piece before if its end moved.
            if speeds[index] >= speeds[index + 1]:
                speeds[index] *= 0.7
                index = max(index - 1, 0)
            else:
                speeds[index + 1] *= 0.7
        rows = [row for piece in pieces for row in piece]
        return rows, (speeds[0], 0.0), (speeds[-1], 0.0)


def _bracket_root(function, low, high, tolerance):
    """Return a root of ``function`` in [low, high] (Illinois), or None without a sign change."""
    f_low, f_high = function(low), function(high)
    if not (f_low * f_high <= 0.0):
        return None
    side = 0
    for _ in range(100):
        if high - low <= tolerance or f_low == f_high:
            break
        middle = (low * f_high - high * f_low) / (f_high - f_low)
        f_middle = function(middle)
        if not math.isfinite(f_middle):
            return None
        if f_middle * f_high > 0.0:
            high, f_high = middle, f_middle
            if side == -1:
                f_low *= 0.5
            side = -1
        elif f_middle * f_low > 0.0:
            low, f_low = middle, f_middle
            if side == 1:
                f_high *= 0.5
            side = 1
        else:
            return middle
    return low if abs(f_low) <= abs(f_high) else high


def _optimal_motion(path, limits, speed_cap):
    """Build the time-optimal profile (see :func:`time_motion`)."""
    if path.arc is None:
        return _vertical_motion(path, limits, speed_cap, 'time_optimal')
    c1, arc_length, c2 = (float(value) for value in path.segment_lengths)
    planner = _ArcPlanner(path, limits, speed_cap)
    v_in = planner.end_speed(c1, True, speed_cap)
    v_out = planner.end_speed(c2, False, speed_cap)
    parts = None
    for _ in range(END_TRIES):
        try:
            arc = planner.solve(v_in, v_out)
        except _NoMotion:
            break
        parts = _with_lines(path, limits, speed_cap, *arc)
        if parts is not None:
            break
        # A line cannot reach the arc's entry (exit) state: ask for a slower one.
        if _with_lines(path, limits, speed_cap, arc[0], arc[1], (0.0, 0.0)) is None:
            v_in = END_RETRY_FACTOR * min(v_in, arc[1][0])
        else:
            v_out = END_RETRY_FACTOR * min(v_out, arc[2][0])
    if parts is None:
        parts = _with_lines(path, limits, speed_cap, *planner.fallback(v_in, v_out))
    if parts is None:
        raise LimitError('time-optimal profile: expected vertical segments that reach the '
                         'arc within the limits, got none')
    lift, arc_rows, descent, entry, exit_state = parts
    pieces = _PieceList()
    pieces.extend(lift)
    pieces.extend(arc_rows, c1)
    pieces.extend(descent)
    law = pieces.law()
    segments = np.array([_rows_duration(lift), _rows_duration(arc_rows),
                         _rows_duration(descent)])
    segments[1] = law.duration - segments[0] - segments[2]
    return TimedMotion(path, 'time_optimal', law.duration, segments,
                       entry[0] ** 2 * planner.kappa_end[0],
                       exit_state[0] ** 2 * planner.kappa_end[1], None, law)


def _with_lines(path, limits, speed_cap, arc_rows, entry, exit_state):
    """Return (lift rows, arc rows, descent rows, entry, exit), or None if a line fails."""
    c1, arc_length, _ = (float(value) for value in path.segment_lengths)
    lift, descent = [], []
    if c1 > 0.0:
        lift = _line_rows((0.0, 0.0, 0.0), (c1, entry[0], entry[1]), limits, speed_cap,
                          0.0, c1)
    elif entry[0] > 0.0 or entry[1] != 0.0:
        lift = None
    end = c1 + arc_length
    if path.length > end:
        descent = _line_rows((end, exit_state[0], exit_state[1]), (path.length, 0.0, 0.0),
                             limits, speed_cap, end, path.length)
    elif exit_state[0] > 0.0 or exit_state[1] != 0.0:
        descent = None
    if lift is None or descent is None:
        return None
    return lift, arc_rows, descent, entry, exit_state
