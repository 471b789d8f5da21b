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
The timed motion along a path: laws s(t) and :class:`TimedMotion`.

Arrays: times t have shape (N,) [s]; path states (s, s', s'', s''') have
shape (N,) [m, m/s, m/s**2, m/s**3]; Cartesian arrays have shape (N, 3), base
frame, SI units.
"""

from dataclasses import dataclass, field, replace
import functools
import math

import numpy as np

from .compiled import kernel
from .errors import InvalidInputError, require_range
from .geometry import _path_rows, PickPlacePath

PROFILES = ('curvature', 'time_optimal')
# The default samples follow the law's pieces: even steps across each constant-jerk piece, at
# most _PIECE_PERIOD apart [s] and at least two per piece, plus both sides of every bound
# (fewer where a motion would need more than _METRICS_SAMPLES samples). Within a piece s' is a
# quadratic in time, so the parabola finds the peak speed between samples; on 967 seeded
# random legs of each join (scripts/sample_accuracy.py) the refined peaks match a 10 us
# reference grid to 3e-9 (speed), 1e-6 (acceleration) and 8e-5 (jerk: a sharp bend just past
# T1 of a paper join).
_PIECE_PERIOD = 2e-4
# A mark of the path (where its curvature rate steps) closer than this share of the duration
# to a bound of the law's pieces is taken as that bound: a piece between them would be a
# rounding error wide.
_SAME_BOUND = 1e-8
_METRICS_SAMPLES = 100000
# A sequence of laws (the curvature profile, seconds long) is sampled by its own pieces too:
# this many even steps across each piece (each panel of the curvature law). With the peaks
# refined between samples, 4 match the 10 us reference to 2e-7 on 953 such legs (8, before
# the refinement took every triple of samples of a piece, to 1.2e-6).
_PIECE_SAMPLES = 4
# A sampled peak is refined by a parabola only where the gaps to its two neighbours are within
# this ratio (see _refined_peaks).
_EVEN_SPACING = 0.25


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

    def bounds(self):
        """Return the times [s] (K + 1,) and path lengths [m] (K + 1,) of the piece bounds."""
        end = self.state(self.times[-1:])[0][0]
        return self.times, np.append(self.s0, end)

    def sample_times(self, count):
        """
        Return sorted times [s]: ``count`` even steps across each piece, each bound on both sides.

        Inside a piece s' is a quadratic and s'' linear in time, so samples that follow the
        pieces follow the law's own scale, whatever the duration.
        """
        return _piece_sample_times(self.sample_bounds(), count)

    def sample_bounds(self):
        """Return the times [s] (K + 1,) across which :meth:`sample_times` steps: the bounds."""
        return self.times

    def state(self, t):
        """Return (s, v, a, j), each shaped like ``t`` (N,)."""
        t = np.asarray(t, dtype=float)
        state = np.empty((4, t.size))
        _piece_states(self.times, self.s0, self.v0, self.a0, self.jerk,
                      np.ascontiguousarray(t).reshape(-1), state)
        return tuple(row.reshape(t.shape) for row in state)


@kernel
def _piece_states(times, s0, v0, a0, jerk, t, state):
    """Fill ``state`` (4, N) with :meth:`_JerkPieces.state` at ``t`` (N,)."""
    for row in range(t.size):
        state[0, row], state[1, row], state[2, row], state[3, row] = _piece_state(
            times, s0, v0, a0, jerk, t[row])


@kernel(inline=True)
def _piece_state(times, s0, v0, a0, jerk, t):
    """Return (s, v, a, j) of :class:`_JerkPieces`' arrays at one time ``t``."""
    index = min(max(np.searchsorted(times, t, side='right') - 1, 0), jerk.size - 1)
    return _cubic_state(t - times[index], s0[index], v0[index], a0[index], jerk[index])


@kernel(inline=True)
def _cubic_state(x, s, v, a, j):
    """Return (s, v, a, j) ``x`` [s] into a constant-jerk piece that starts in state (s, v, a)."""
    return (s + x * (v + x * (a / 2.0 + x * j / 6.0)), v + x * (a + x * j / 2.0), a + x * j, j)


class _PieceList:
    """Collects constant-jerk pieces (duration, s, v, a, j) into a :class:`_JerkPieces`."""

    def __init__(self):
        self.blocks = []
        self.offsets = []

    def extend(self, rows, s_offset=0.0):
        """Append ``rows`` ((K, 5) or a sequence of such rows), s + ``s_offset``, none empty."""
        # Read by law(), in one array: a Python call per row (a scan's rows are hundreds of
        # pieces), or NumPy's per block, would cost more than the arithmetic.
        self.blocks.append(np.asarray(rows, dtype=float).reshape(-1, 5))
        self.offsets.append(s_offset)

    def law(self):
        """Return the pieces so far as a law, without those of no duration."""
        if not self.blocks:
            return _pieces_of(np.empty((0, 5)))
        rows = np.concatenate(self.blocks)
        start = 0
        for block, offset in zip(self.blocks, self.offsets):
            rows[start:start + block.shape[0], 1] += offset
            start += block.shape[0]
        lasting = rows[:, 0] > 0.0
        # Selecting rows costs more than the rest: only where a piece has no duration.
        return _pieces_of(rows if lasting.all() else rows[lasting])


def _pieces_of(rows):
    """Return the :class:`_JerkPieces` of ``rows`` (K, 5): duration, s, v, a, j of each piece."""
    times = np.empty(rows.shape[0] + 1)
    times[0] = 0.0
    np.cumsum(rows[:, 0], out=times[1:])
    return _JerkPieces(times, rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4])


def _piece_sample_times(bounds, count):
    """
    Return sorted times [s]: ``count`` even steps across each interval of ``bounds`` (K + 1,).

    ``count`` is one number, or one per interval (K,), each >= 1. Each interior
    bound is taken 1e-9 of the whole span off on both sides (the law is the next
    piece's at the bound itself), the ends exactly (:func:`_times_across`).
    """
    bounds = np.ascontiguousarray(bounds, dtype=float)
    counts = np.broadcast_to(np.asarray(count, dtype=np.int64), (bounds.size - 1,))
    return _times_across(bounds, np.ascontiguousarray(counts), math.inf)


@kernel
def _sequence_sample_times(bounds, ends, starts, durations, count):
    """
    Return :meth:`_Sequence.sample_times`: ``count`` even steps across each law's intervals.

    Law i has the bounds ``bounds[ends[i]:ends[i + 1]]`` (:func:`_times_across` of them),
    the duration ``durations[i]`` and starts at ``starts[i]`` (``starts`` (L + 1,) ends with
    the sequence's end); its times are kept 1e-9 of the whole span inside it (NumPy's clip:
    the larger of the time and that, then the smaller of that and the duration less it),
    then moved by its start. Sorted with ``starts``: the operations of the NumPy formulas
    these were first written in, so the same times bit for bit.
    """
    epsilon = 1e-9 * starts[-1]
    total = starts.size
    for law in range(durations.size):
        total += (ends[law + 1] - ends[law] - 1) * (count + 1)
    t = np.empty(total)
    row = 0
    for law in range(durations.size):
        t[row] = starts[law]
        row += 1
        law_bounds = bounds[ends[law]:ends[law + 1]]
        law_times = _times_across(law_bounds, np.full(law_bounds.size - 1, count, np.int64),
                                  np.inf)
        high = durations[law] - epsilon
        for value in law_times:
            value = value if value > epsilon else epsilon
            t[row] = starts[law] + (value if value < high else high)
            row += 1
    t[row] = starts[-1]
    # In order unless a law is shorter than the offsets off its ends.
    _sort_unless_sorted(t)
    return t


def _pieces_law(rows, s_offset=0.0):
    pieces = _PieceList()
    pieces.extend(rows, s_offset)
    return pieces.law()


def _rows_duration(rows):
    """Return the duration [s] of the pieces ``rows``: an array (K, 5), or a list of rows."""
    if isinstance(rows, np.ndarray):
        # The scans' rows stay arrays: hundreds of pieces, summed without a Python loop.
        return float(np.sum(rows[:, 0]))
    return float(sum(row[0] for row in rows))


@dataclass(frozen=True, eq=False)
class _Sequence:
    """Laws run one after the other."""

    laws: tuple

    @property
    def duration(self):
        return float(sum(law.duration for law in self.laws))

    @functools.cached_property
    def _starts(self):
        """Return the times [s] (K + 1,) where each law starts, and the end (read-only)."""
        starts = np.cumsum([0.0] + [law.duration for law in self.laws])
        starts.setflags(write=False)
        return starts

    @functools.cached_property
    def _bounds(self):
        """Return :meth:`bounds`, computed once (read-only arrays)."""
        times, lengths = [], []
        for start, law in zip(self._starts, self.laws):
            law_times, law_lengths = law.bounds()
            times.append(start + law_times)
            lengths.append(law_lengths)
        bounds = np.concatenate(times), np.concatenate(lengths)
        for values in bounds:
            values.setflags(write=False)
        return bounds

    def bounds(self):
        """
        Return the times [s] and path lengths [m] where each law starts, and the end.

        Within a law its own ``bounds()`` (:meth:`_JerkPieces.bounds`; the curvature
        profile's arc law gives its ends). Read-only: computed once, asked for by the
        samples, the jerk steps and the path's marks.
        """
        return self._bounds

    def sample_times(self, count):
        """
        Return sorted times [s]: each law's :meth:`sample_times`, its ends on both sides.

        Each law's times from its ``sample_bounds()`` (:func:`_sequence_sample_times`, in one
        compiled pass).
        """
        bounds = [law.sample_bounds() for law in self.laws]
        return _sequence_sample_times(
            np.concatenate(bounds), np.cumsum([0] + [values.size for values in bounds]),
            self._starts, np.array([law.duration for law in self.laws]), count)

    def newton_times(self, lengths, t, factor, duration):
        """
        Return the times ``t`` (N,) after three Newton steps towards s(t) = ``lengths`` (N,).

        The sequence is read slowed down by ``factor`` over ``duration`` [s], as
        :meth:`TimedMotion.path_state` reads it; each step is kept within the duration, and
        a time where s' <= 1e-9 stays.
        """
        for _ in range(3):
            if np.any(t < 0.0) or np.any(t > duration):
                s, v, _, _ = self.state(np.clip(t, 0.0, duration) / factor)
            else:
                s, v, _, _ = self.state(t / factor)
            if factor != 1.0:
                v = v / factor
            moving = v > 1e-9
            t = np.where(moving, np.clip(t - (s - lengths) / np.where(moving, v, 1.0), 0.0,
                                         duration), t)
        return t

    def state(self, t):
        """
        Return (s, v, a, j) at times ``t`` (N,): each time's law at its time from that law's start.

        The law of a time is the last starting at or before it (the first for earlier
        times). The times, sorted (most callers' are), are split into one slice per law:
        one call of each law's ``state`` whatever the times (the values do not depend on
        which other times a law is asked for at once).
        """
        starts = self._starts
        order = None
        if t.size > 1 and not np.all(t[1:] >= t[:-1]):
            order = np.argsort(t, kind='stable')
            t = t[order]
        # Law i takes the times from the first at or after its start to the first at or after
        # the next law's start; the first law those before, the last those after.
        ends = np.searchsorted(t, starts[1:-1], side='left').tolist()
        rows = np.empty((4, t.size))
        for law, start, first, end in zip(self.laws, starts, [0] + ends, ends + [t.size]):
            if end > first:
                rows[:, first:end] = law.state(t[first:end] - start)
        if order is not None:
            sorted_rows, rows = rows, np.empty_like(rows)
            rows[:, order] = sorted_rows
        return tuple(rows)


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
    law : _JerkPieces or _Sequence
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
    n_nodes: int | None
    law: _JerkPieces | _Sequence = field(repr=False)
    time_scale: float = 1.0
    node_period: float | None = None
    # Peaks (speed, acceleration, jerk) on the default samples, once sampled_norms has run: the
    # final limit check and metrics() share one sample set; scaled() scales them.
    _peaks: tuple | None = field(default=None, init=False, repr=False)
    # That sample set itself, (t, position, velocity, acceleration, jerk): the planner derives
    # its knots, joint peaks and jerk steps from it instead of sampling the motion again.
    _states: tuple | None = field(default=None, init=False, repr=False)
    # The path's marks in time (_mark_times), once: the samples' bounds and the jerk steps
    # both read them. Not carried by scaled(): times x factor would round differently.
    _marks: np.ndarray | None = field(default=None, init=False, repr=False)

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
        # On floats: NumPy's calls on three numbers cost more than the checks (the sum of
        # three is NumPy's, in order).
        values = segments.tolist() if segments.shape == (3,) else None
        if (values is None or not all(0.0 <= value < math.inf for value in values)
                or abs(values[0] + values[1] + values[2] - duration) > 1e-9 * duration):
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
        # Two reductions for every check: a NaN makes both NaN, and NaN fails the comparisons.
        low, high = (float(t.min()), float(t.max())) if t.size else (0.0, 0.0)
        if t.ndim != 1 or not (low >= -tolerance and high <= self.duration + tolerance):
            raise InvalidInputError(
                f't: expected finite times of shape (N,) in [0, {self.duration:.9g}] s, got '
                f'shape {t.shape}, range [{low:.9g}, {high:.9g}]')
        if low < 0.0 or high > self.duration:
            t = np.clip(t, 0.0, self.duration)
        factor = self.time_scale
        s, v, a, j = self.law.state(t / factor)
        if factor == 1.0:
            # Dividing by 1 changes no value: the law's own rows.
            return s, v, a, j
        return s, v / factor, a / factor ** 2, j / factor ** 3

    def state_at(self, t):
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

    def metrics(self, sample_period=None):
        """
        Return the motion's numbers, on the default samples or every ``sample_period``.

        Parameters
        ----------
        sample_period : float, optional
            Time between samples [s], in (0, 0.1], plus both sides of every
            piece bound of the law; longer where the motion would need more
            than ``_METRICS_SAMPLES`` samples. Omitted: the samples of
            :meth:`sampled_norms`, which follow the law's pieces. Each peak is
            refined between the samples.

        Returns
        -------
        dict
            ``duration`` [s], ``segment_durations`` (list of 3) [s],
            ``peak_speed`` [m/s], ``peak_accel`` [m/s**2], ``peak_jerk``
            [m/s**3] (the steps at T1/T2 are not jerk), ``accel_jump_T1`` and
            ``accel_jump_T2`` [m/s**2]; plain floats.

        """
        if sample_period is None:
            if self._peaks is None:
                self.sampled_norms()
            speed, accel, jerk = self._peaks
        else:
            period = require_range('sample_period', sample_period, 0.0, 0.1, low_open=True,
                                   unit='s')
            period = max(period, self.duration / _METRICS_SAMPLES)
            speed, accel, jerk = _sampled(self, _check_times(self, period))[3]
        return {'duration': float(self.duration),
                'segment_durations': [float(value) for value in self.segment_durations],
                'peak_speed': speed, 'peak_accel': accel, 'peak_jerk': jerk,
                'accel_jump_T1': float(self.accel_jump_T1),
                'accel_jump_T2': float(self.accel_jump_T2)}

    def sampled_norms(self):
        """
        Return the motion sampled as :meth:`metrics` samples it by default.

        Even steps across each of the law's constant-jerk pieces (split where
        the path's curvature rate steps, :func:`_smooth_bounds`), at most
        ``_PIECE_PERIOD`` apart and at least two per piece (fewer samples where
        the motion would need more than ``_METRICS_SAMPLES``), and both sides of
        every bound; a sequence of laws (the curvature profile) at
        ``_PIECE_SAMPLES`` even steps across each of its pieces
        (:meth:`_Sequence.sample_times`). The peaks are kept for :meth:`metrics`:
        the maximum of the parabola through three samples of one piece, where it
        lies between them, counts too (:func:`_refined_peaks`), so that a peak
        between samples is not missed.

        Returns
        -------
        tuple of numpy.ndarray
            (s [m], |velocity| [m/s], |acceleration| [m/s**2], |jerk|
            [m/s**3]), each of shape (N,).

        """
        bounds = _smooth_bounds(self)
        t = self._norm_times(bounds)
        s, states, norms, peaks = _sampled(self, t, bounds)
        object.__setattr__(self, '_peaks', peaks)
        object.__setattr__(self, '_states', (t, *states))
        return (s, *norms)

    def _norm_times(self, bounds):
        """Return the sorted sample times [s] (N,) of :meth:`sampled_norms` (its bounds)."""
        if isinstance(self.law, _Sequence):
            return np.minimum(self.law.sample_times(_PIECE_SAMPLES) * self.time_scale,
                              self.duration)
        return _piece_check_times(self, bounds)

    def sampled_states(self):
        """
        Return the samples of :meth:`sampled_norms`, as vectors.

        Even steps at most ``_PIECE_PERIOD`` apart (at least two) across each of
        the law's constant-jerk pieces (split where the path's curvature rate
        steps) and both sides of every bound; the
        curvature profile's at ``_PIECE_SAMPLES`` even steps across each of its
        pieces (the planner's knots, joint peaks and jerk steps read them too).

        Returns
        -------
        tuple of numpy.ndarray
            Times [s] (N,), sorted, and position [m], velocity [m/s],
            acceleration [m/s**2] and jerk [m/s**3], each (N, 3). Both
            sides of every piece bound are samples (1e-9 of the duration
            off the bound).

        """
        if self._states is None:
            self.sampled_norms()
        return self._states

    def jerk_steps(self):
        """
        Return the times [s] (K,) and sizes [m/s**3] (K,) of the steps of the TCP jerk.

        The jerk steps where the law's third derivative does (its piece bounds;
        a sequence of laws: theirs and those of their pieces) and where the
        path's curvature rate does (T1, T2 and, with a G2 join, where the
        transitions meet the ellipse). At a piece bound where the
        path is smooth only the law's jerk steps (s, s' and s'' are
        continuous), along the unit tangent: the size is read from the law's
        pieces (a sequence's: its s''' on both sides). At the path's marks it
        is the norm of the difference of the one-sided jerk vectors, 1e-9 of
        the duration off the mark on both sides (a piece bound there is
        counted in it).
        """
        epsilon = 1e-9 * self.duration
        marks = self._mark_times()
        law = self.law
        law_times = getattr(law, 'times', None)
        if law_times is not None and self.path.arc is not None:
            # The time-optimal profile's: the law's steps and the marks' in one compiled pass.
            factor = self.time_scale
            return _piece_jerk_steps(law_times, law.s0, law.v0, law.a0, law.jerk, factor,
                                     factor ** 2, factor ** 3, marks, epsilon,
                                     float(self.duration), self.path._frame,
                                     *self.path.bend._table)
        if law_times is not None:
            times = law_times[1:-1] * self.time_scale
            sizes = np.abs(np.diff(self.law.jerk)) / self.time_scale ** 3
        else:
            # A sequence of laws (the curvature profile): the bounds of its laws and of their
            # constant-jerk pieces (the Ruckig lines' switches), s''' read on both sides.
            times = np.unique(self.law.bounds()[0])[1:-1] * self.time_scale
            jerk = self.path_state(np.concatenate((np.maximum(times - epsilon, 0.0),
                                                   np.minimum(times + epsilon, self.duration))))[3]
            sizes = np.abs(jerk[times.size:] - jerk[:times.size])
        jerk = np.zeros((0, 3))
        if marks.size:
            jerk = self.state_at(np.concatenate((np.maximum(marks - epsilon, 0.0),
                                                 np.minimum(marks + epsilon, self.duration))))[3]
        return _merged_steps(np.ascontiguousarray(times), np.ascontiguousarray(sizes), marks,
                             jerk, epsilon, float(self.duration))

    def _mark_times(self):
        """Return the times [s] at which the path's curvature rate steps (T1, T2, G2 ends)."""
        if self._marks is None:
            marks = self._marks_found()
            marks.setflags(write=False)
            object.__setattr__(self, '_marks', marks)
        return self._marks

    def _marks_found(self):
        """Return :meth:`_mark_times`, found on the law."""
        path = self.path
        if path.bend is None:
            return np.zeros(0)
        bend = path.bend
        marks = np.array(path.segment_ends[1:3])
        if path.join == 'g2':
            marks = np.concatenate((marks, path.segment_ends[1] + bend.s_from_t(
                np.array([math.pi - bend.span_1, bend.span_2]))))
        law = self.law
        if isinstance(law, _JerkPieces):
            # Each mark's piece, then the root of that piece's cubic s(t) (one compiled pass).
            times = np.empty(marks.size)
            _times_at_lengths(law.times, law.s0, law.v0, law.a0, law.jerk,
                              np.ascontiguousarray(marks, dtype=float), times)
            return np.minimum(times * self.time_scale, self.duration)
        # s(t) is increasing: interpolate each mark between the lengths at the law's piece
        # bounds (or samples), then refine by Newton steps on the law (where s' = 0 the
        # interpolation stays).
        bound_times, bound_lengths = law.bounds()
        t = np.interp(marks, bound_lengths, bound_times * self.time_scale)
        return law.newton_times(marks, t, self.time_scale, self.duration)

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
        scaled = replace(self, duration=self.duration * factor,
                         segment_durations=self.segment_durations * factor,
                         accel_jump_T1=self.accel_jump_T1 / factor ** 2,
                         accel_jump_T2=self.accel_jump_T2 / factor ** 2,
                         time_scale=self.time_scale * factor,
                         node_period=None if self.node_period is None
                         else self.node_period * factor)
        if self._peaks is not None:
            # The same samples, slowed down: the peaks scale exactly (their samples are
            # ``factor`` times further apart in time, no sparser along the path).
            speed, accel, jerk = self._peaks
            object.__setattr__(scaled, '_peaks',
                               (speed / factor, accel / factor ** 2, jerk / factor ** 3))
        if self._states is not None:
            t, position, velocity, acceleration, jerk = self._states
            object.__setattr__(scaled, '_states', (
                t * factor, position, velocity / factor, acceleration / factor ** 2,
                jerk / factor ** 3))
        return scaled


def _cartesian(path, s, v, a, j):
    """Return position, velocity, acceleration and jerk (N, 3) from the path state."""
    return _cartesian_and_norms(path, s, v, a, j)[0]


def _cartesian_and_norms(path, s, v, a, j):
    """
    Return (position, velocity, acceleration, jerk), each (N, 3), and their norms (3, N).

    The norms are those of velocity, acceleration and jerk; on a path with an arc
    one compiled pass evaluates the path and the products (:func:`_state_rows`).
    """
    states, norms = np.empty((4, s.size, 3)), np.empty((3, s.size))
    if path.arc is None:
        _cartesian_rows(*path.rows_at_lengths(s), v, a, j, states)
        for index in range(3):
            norms[index] = np.sqrt(np.einsum('ij,ij->i', states[index + 1], states[index + 1]))
    else:
        _state_rows(*(np.ascontiguousarray(value, dtype=float) for value in (s, v, a, j)),
                    path._frame, *path.bend._table, states, norms)
    return tuple(states), norms


@kernel
def _state_rows(s, v, a, j, frame, panel_t, panel_s, quintics, states, norms):
    """
    Fill ``states`` (4, N, 3) as :func:`_cartesian_rows` does, and ``norms`` (3, N).

    The path's rows at ``s`` come from :func:`~ellipath_ros.core.geometry._path_rows`
    (``frame`` and the table are the path's); ``norms`` holds the norms of the
    velocity, acceleration and jerk.
    """
    rows = np.empty((4, 3, s.size))
    _path_rows(s, frame, panel_t, panel_s, quintics, rows)
    _cartesian_rows(rows[0], rows[1], rows[2], rows[3], v, a, j, states)
    for index in range(3):
        vectors = states[index + 1]
        for row in range(s.size):
            x, y, z = vectors[row, 0], vectors[row, 1], vectors[row, 2]
            norms[index, row] = math.sqrt(x * x + y * y + z * z)


@kernel
def _cartesian_rows(position, tangent, curvature, rate, v, a, j, states):
    """Fill ``states`` (4, N, 3) from the path's rows (3, N) and its law's v, a, j (N,)."""
    for row in range(v.size):
        speed, accel, jerk = v[row], a[row], j[row]
        if (rate[0, row] == 0.0 and rate[1, row] == 0.0 and rate[2, row] == 0.0
                and abs(speed) < 1e100):
            # No curvature rate (a vertical line): the cube only signs a zero product, and
            # x * x * x has pow's sign and (below 1e100) its finiteness, without pow's cost.
            cube = speed * speed * speed
        else:
            cube = speed ** 3.0
        for axis in range(3):
            states[0, row, axis] = position[axis, row]
            states[1, row, axis] = speed * tangent[axis, row]
            states[2, row, axis] = (accel * tangent[axis, row]
                                    + (speed * speed) * curvature[axis, row])
            states[3, row, axis] = (jerk * tangent[axis, row]
                                    + (3.0 * speed * accel) * curvature[axis, row]
                                    + cube * rate[axis, row])


@kernel
def _times_at_lengths(times, s0, v0, a0, jerk, lengths, out):
    """
    Fill ``out`` (N,) with the first law times [s] at which s reaches ``lengths`` (N,).

    The law is :class:`_JerkPieces`' arrays (s never falls); each length is found
    in the last piece starting at or before it, as the root of the piece's cubic
    by Newton steps kept inside a bisection bracket (to 1e-15 of the piece).
    """
    last = jerk.size - 1
    for row in range(lengths.size):
        target = lengths[row]
        index = min(max(np.searchsorted(s0, target, side='right') - 1, 0), last)
        start, s, v, a, j = times[index], s0[index], v0[index], a0[index], jerk[index]
        low, high = 0.0, times[index + 1] - start
        x = 0.5 * high
        for _ in range(100):
            error = s + x * (v + x * (a / 2.0 + x * j / 6.0)) - target
            if error > 0.0:
                high = x
            else:
                low = x
            if high - low <= 1e-15 * (times[index + 1] - start) or error == 0.0:
                break
            slope = v + x * (a + x * j / 2.0)
            x = x - error / slope if slope > 0.0 else 0.5 * (low + high)
            if not low < x < high:
                x = 0.5 * (low + high)
        out[row] = start + x


def _piece_check_times(motion, bounds):
    """
    Return the default samples of ``motion`` (a law of constant-jerk pieces), sorted [s].

    Even steps across each interval of ``bounds`` (:func:`_smooth_bounds`), at most
    ``_PIECE_PERIOD`` apart (longer where the motion would need more than
    ``_METRICS_SAMPLES`` samples) and at least two, so that every interval has a sample
    inside it for :func:`_refined_peaks`; both sides of every bound (the times of
    :func:`_piece_sample_times`, in one compiled pass: :func:`_even_piece_times`).
    """
    return _even_piece_times(np.ascontiguousarray(bounds, dtype=float),
                             max(_PIECE_PERIOD, motion.duration / _METRICS_SAMPLES),
                             float(motion.duration))


@kernel
def _even_piece_times(bounds, period, duration):
    """
    Return :func:`_piece_sample_times` of ``bounds`` (K + 1,), ceil(width / period) (>= 2) each.

    Each time at most ``duration``.
    """
    intervals = bounds.size - 1
    counts = np.empty(intervals, np.int64)
    for interval in range(intervals):
        counts[interval] = max(math.ceil((bounds[interval + 1] - bounds[interval]) / period), 2)
    return _times_across(bounds, counts, duration)


@kernel
def _times_across(bounds, counts, duration):
    """
    Return sorted times [s]: ``counts[i]`` (K,) even steps across interval i of ``bounds``.

    Interval i of ``bounds`` (K + 1,) gets the interior steps 1 .. counts[i] - 1 at
    ``start + width * (step / count)``; each interior bound is taken 1e-9 of the whole span
    off on both sides (at most ``bounds[-1]``, at least 0), the ends exactly; each time at
    most ``duration``. The floating-point operations of the NumPy formulas these times were
    first written in, so the same times bit for bit, in one compiled pass.
    """
    intervals = bounds.size - 1
    epsilon = 1e-9 * bounds[-1]
    total = 2 * intervals
    for interval in range(intervals):
        total += counts[interval] - 1
    t = np.empty(total)
    t[0] = bounds[0]
    row = 1
    for interval in range(intervals):
        start, width, count = bounds[interval], bounds[interval + 1] - bounds[interval], counts[
            interval]
        if interval > 0:
            t[row] = min(start + epsilon, bounds[-1])
            row += 1
        for step in range(1, count):
            t[row] = start + width * (step / count)
            row += 1
        if interval < intervals - 1:
            t[row] = max(bounds[interval + 1] - epsilon, 0.0)
            row += 1
    t[row] = bounds[-1]
    # In order unless a piece is narrower than the offsets off its bounds.
    _sort_unless_sorted(t)
    for row in range(total):
        t[row] = min(t[row], duration)
    return t


@kernel(inline=True)
def _sort_unless_sorted(t):
    """
    Sort ``t`` (N,) in place if it is out of order.

    Sample times are assembled in order but for rare narrow pieces; numba's sort of
    nearly sorted times would cost three times the assembly.
    """
    for row in range(1, t.size):
        if t[row] < t[row - 1]:
            t.sort()
            return


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


def _smooth_bounds(motion):
    """
    Return the sorted times [s] (K + 1,) between which the norms of ``motion`` are smooth.

    The bounds of its law's pieces, and the path's marks where its curvature rate
    steps (:meth:`TimedMotion._mark_times`: T1, T2, the ends of a G2 join's
    transitions) that are not within ``_SAME_BOUND`` of one: there the jerk steps
    inside a piece of the law. A sequence of laws (the curvature profile, paper join
    only) has its laws' bounds and those of their pieces: its laws meet at T1 and T2,
    its only marks (on 199 of 199 seeded legs none added a bound; finding them by
    Newton steps on a sequence cost 0.1 ms of CPU a leg).
    """
    law = motion.law
    if not isinstance(law, _JerkPieces):
        return law.bounds()[0] * motion.time_scale
    bounds = law.times * motion.time_scale
    marks = motion._mark_times()
    if marks.size:
        apart = _farther_than(marks, bounds, _SAME_BOUND * motion.duration)
        bounds = np.sort(np.concatenate((bounds, marks[apart])))
    return bounds


@kernel
def _piece_jerk_steps(times, s0, v0, a0, jerk, factor, factor_2, factor_3, marks, epsilon,
                      duration, frame, panel_t, panel_s, quintics):
    """
    Return :meth:`TimedMotion.jerk_steps` of a law of constant-jerk pieces on a path with an arc.

    The law is :class:`_JerkPieces`' arrays slowed down by ``factor`` (its square and cube
    given, as path_state computes them), ``marks`` (M,) the path's marks in time, ``frame``
    and the table the path's (:func:`_state_rows`). The law's steps and the jerk vectors
    ``epsilon`` before and after each mark (:meth:`TimedMotion.state_at` there: the law's
    state by :func:`_piece_state`, divided by the factor's powers where it is not 1), merged
    by :func:`_merged_steps`: the operations of path_state, state_at and jerk_steps' NumPy
    formulas, in one compiled pass.
    """
    count = marks.size
    law_rows = np.empty((4, 2 * count))
    for row in range(2 * count):
        if row < count:
            t = max(marks[row] - epsilon, 0.0)
        else:
            t = min(marks[row - count] + epsilon, duration)
        s, v, a, j = _piece_state(times, s0, v0, a0, jerk, t / factor)
        if factor != 1.0:
            v, a, j = v / factor, a / factor_2, j / factor_3
        law_rows[0, row], law_rows[1, row], law_rows[2, row], law_rows[3, row] = s, v, a, j
    states, norms = np.empty((4, 2 * count, 3)), np.empty((3, 2 * count))
    _state_rows(law_rows[0], law_rows[1], law_rows[2], law_rows[3], frame, panel_t, panel_s,
                quintics, states, norms)
    sizes = np.empty(jerk.size - 1)
    for piece in range(sizes.size):
        sizes[piece] = abs(jerk[piece + 1] - jerk[piece]) / factor_3
    return _merged_steps(times[1:-1] * factor, sizes, marks, states[3], epsilon, duration)


@kernel
def _merged_steps(times, sizes, marks, jerk, epsilon, duration):
    """
    Return :meth:`TimedMotion.jerk_steps` from the law's steps and the jerk at the marks.

    ``times`` and ``sizes`` (K,) are the law's steps, ``marks`` (M,) the path's, ``jerk``
    (2 M, 3) the jerk just before and just after each mark. Steps within ``epsilon`` of a
    mark are counted in the mark's (the norm of the difference); sorted (stable), the first
    of equal times kept, only those inside (0, ``duration``). The operations of the NumPy
    formulas these were first written in (the norm adds the squares in order), in one pass.
    """
    apart = _farther_than(times, marks, epsilon)
    kept = np.flatnonzero(apart)
    count = kept.size + marks.size
    all_times, all_sizes = np.empty(count), np.empty(count)
    for row in range(kept.size):
        all_times[row], all_sizes[row] = times[kept[row]], sizes[kept[row]]
    for mark in range(marks.size):
        row = kept.size + mark
        all_times[row] = marks[mark]
        x = jerk[marks.size + mark, 0] - jerk[mark, 0]
        y = jerk[marks.size + mark, 1] - jerk[mark, 1]
        z = jerk[marks.size + mark, 2] - jerk[mark, 2]
        all_sizes[row] = math.sqrt(x * x + y * y + z * z)
    order = np.argsort(all_times, kind='mergesort')
    out_times, out_sizes = np.empty(count), np.empty(count)
    found = 0
    for rank in range(count):
        here = all_times[order[rank]]
        if rank > 0 and not here - all_times[order[rank - 1]] > 0.0:
            continue
        if here > 0.0 and here < duration:
            out_times[found], out_sizes[found] = here, all_sizes[order[rank]]
            found += 1
    return out_times[:found], out_sizes[:found]


@kernel
def _farther_than(values, others, distance):
    """
    Return whether each of ``values`` (N,) is farther than ``distance`` from all ``others``.

    As ``np.abs(values[:, None] - others[None, :]).min(axis=1) > distance`` (the same
    differences), without the (N, M) arrays: a few marks against hundreds of bounds.
    """
    apart = np.empty(values.size, np.bool_)
    for row in range(values.size):
        nearest = np.inf
        for other in others:
            nearest = min(nearest, abs(values[row] - other))
        apart[row] = nearest > distance
    return apart


def _sampled(motion, t, bounds=None):
    """
    Return (s, states, norms, peaks) of ``motion`` at sorted times ``t`` (N,) within it.

    ``states`` are :meth:`TimedMotion.state_at`'s four (N, 3) arrays, ``norms`` the
    norms (3, N) of velocity, acceleration and jerk, ``peaks`` their largest values
    (three floats), refined between the samples of each interval of ``bounds``
    (:func:`_smooth_bounds` when omitted; :func:`_refined_peaks`).
    """
    bounds = _smooth_bounds(motion) if bounds is None else bounds
    law = motion.law
    if isinstance(law, _JerkPieces):
        # The times are the motion's own (sorted, within it): the law's state and each
        # sample's interval in one compiled pass, as path_state and np.searchsorted give them.
        t = np.ascontiguousarray(t, dtype=float)
        rows, pieces = np.empty((4, t.size)), np.empty(t.size, np.int64)
        factor = motion.time_scale
        _sorted_law_rows(t, float(motion.duration), factor, factor ** 2, factor ** 3,
                         law.times, law.s0, law.v0, law.a0, law.jerk,
                         np.ascontiguousarray(bounds[1:-1], dtype=float), rows, pieces)
        s, v, a, j = rows
    else:
        s, v, a, j = motion.path_state(t)
        pieces = np.searchsorted(bounds[1:-1], t, side='right')
    states, norms = _cartesian_and_norms(motion.path, s, v, a, j)
    peaks = np.empty(3)
    _refined_peaks(np.ascontiguousarray(t, dtype=float), pieces, norms, peaks)
    return s, states, norms, tuple(float(peak) for peak in peaks)


@kernel
def _sorted_law_rows(t, duration, factor, factor_2, factor_3, times, s0, v0, a0, jerk, inner,
                     rows, pieces):
    """
    Fill ``rows`` (4, N) with :meth:`TimedMotion.path_state` at sorted ``t`` (N,), and ``pieces``.

    The law is :class:`_JerkPieces`' arrays slowed down by ``factor`` (its square and cube
    given, as path_state computes them); ``pieces`` (N,) holds each time's interval of the
    bounds whose interior ones are ``inner`` (``np.searchsorted(inner, t, side='right')``).
    Both searches walk along the sorted times: the same indices as a search per time, and
    the same arithmetic as :func:`_piece_states`.
    """
    last = jerk.size - 1
    piece, interval = 0, 0
    # A division by 1 changes no value: an unscaled law (the first sampling) skips them.
    scaled = factor != 1.0
    for row in range(t.size):
        x = min(max(t[row], 0.0), duration)
        if scaled:
            x /= factor
        while piece < times.size and times[piece] <= x:
            piece += 1
        index = min(max(piece - 1, 0), last)
        x -= times[index]
        j, a, v = jerk[index], a0[index], v0[index]
        rows[0, row] = s0[index] + x * (v + x * (a / 2.0 + x * j / 6.0))
        speed, accel = v + x * (a + x * j / 2.0), a + x * j
        if scaled:
            speed, accel, j = speed / factor, accel / factor_2, j / factor_3
        rows[1, row], rows[2, row], rows[3, row] = speed, accel, j
        while interval < inner.size and inner[interval] <= t[row]:
            interval += 1
        pieces[row] = interval


@kernel
def _refined_peaks(t, pieces, norms, peaks):
    """
    Fill ``peaks`` (3,) with the largest of each row of ``norms`` (3, N) at sorted ``t`` (N,).

    Every three consecutive samples of one piece (``pieces``, (N,): the
    interval of :func:`_smooth_bounds` of each sample; the norms are smooth
    within one), spaced about evenly
    (neither gap below ``_EVEN_SPACING`` of the other), add the vertex of the
    parabola through them where it is a maximum between the outer two: a peak
    between samples is then missed by a term of third order in the sample
    spacing instead of second (none for the speed, a quadratic within a piece),
    also where it lies between a piece's last two samples.

    A triple that cannot raise the largest value is skipped before its divisions: the
    vertex that passes the checks below lies within the longer gap of the middle sample,
    where the parabola's slope is at most (M - m) / the shorter gap (M and m the
    triple's largest and smallest value), so it is at most (M - m) (longer gap) / (2
    shorter gap) <= 2 (M - m) above the middle sample; a triple with M + 3 (M - m) below
    the largest value (the norms are >= 0; the rest is room for rounding) never raises it.
    """
    count = t.size
    for row in range(3):
        values = norms[row]
        best = values[0]
        for index in range(1, count):
            best = max(best, values[index])
        for index in range(1, count - 1):
            here = values[index]
            highest = max(values[index - 1], here, values[index + 1])
            lowest = min(values[index - 1], here, values[index + 1])
            if (highest + 3.0 * (highest - lowest)) * (1.0 + 1e-12) < best:
                continue
            if pieces[index - 1] != pieces[index] or pieces[index + 1] != pieces[index]:
                continue
            h_1, h_2 = t[index] - t[index - 1], t[index + 1] - t[index]
            # Only about even spacing: beside a sample just off a bound (or a step of the
            # path's curvature between samples) the vertex would extrapolate rounding or a
            # step, not a peak.
            if min(h_1, h_2) < _EVEN_SPACING * max(h_1, h_2) or h_1 <= 0.0:
                continue
            d_1 = (here - values[index - 1]) / h_1
            d_2 = (values[index + 1] - here) / h_2
            curvature = 2.0 * (d_2 - d_1) / (h_1 + h_2)
            if curvature < 0.0:
                slope = (d_1 * h_2 + d_2 * h_1) / (h_1 + h_2)
                # The vertex lies slope / -curvature after the middle sample: between the
                # outer two it interpolates; beyond them it would extrapolate.
                if h_1 * curvature <= slope <= -h_2 * curvature:
                    best = max(best, here - slope * slope / (2.0 * curvature))
        peaks[row] = best
