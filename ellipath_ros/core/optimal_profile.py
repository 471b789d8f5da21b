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
The time-optimal profile (beyond the paper): jerk-limited path-space scans along the arc.

The fastest motion found along the path with speed <= max_speed,
acceleration vector norm <= max_accel (tangential s'' and normal
s'**2 kappa together), jerk vector norm <= max_jerk (jerk =
p''' s'**3 + 3 p'' s' s'' + p' s''', p = p(s)), acceleration step at
T1/T2 (s'**2 times the arc's end curvature, the lines being straight)
<= max_accel_jump, an optional speed cap s' <= speed_cap(s), from rest to
rest. See :func:`~ellipath_ros.core.timing.time_motion` for the construction; the
scan itself is :mod:`~ellipath_ros.core.arc_scan`, this module joins two scans, handles speed
valleys and end speeds, the fallback and the vertical lines.
"""

import functools
import math
import struct

import numpy as np

from .arc_scan import (
    _ACCEL_SQUARED, _advance, _ADVANCED, _arc_tables, _bisect_right, _CELL, _COUNT, _END,
    _FAILURES, _jerk_range, _LIVE, _new_scan, _NoMotion, _OUT_OF_STEPS, _py_max, _py_min,
    _reversed_rows, _rows, _run, _Scanner, _speed_at, _SPEED_TARGET, _state, _STATUS,
    _STOPPED, _table_at, _time_at, _TWO)
from .compiled import kernel
from .errors import InvalidInputError, LimitError
from .limits import (
    _ACCEL_MARGIN, _cap_values, _even_samples, _JERK_MARGIN, _LIMIT_SAMPLES, _SPEED_MARGIN)
from .motion import _PieceList, _rows_duration, TimedMotion
from .ruckig_lines import (
    _capped_line_speed, _constant_limits, _line_limits, _line_speed, _reach_speed, _ruckig_rows,
    _straight_motion)

# The key of a solved vertical line: its start and end states and its stretch.
_EIGHT_FLOATS = struct.Struct('<8d')
# Grid of the curvature tables along the arc (intervals; more for very tight bends).
_TABLE_INTERVALS = 2048
_TABLE_INTERVALS_MAX = 16384
# Interior speed valleys: first try at this share of the local speed ceiling, then lower.
_VALLEY_SHARE = 0.9
_VALLEY_RETRY_FACTOR = 0.6
_VALLEY_TRIES = 4
# A valley speed that came down is then bisected this often (to an eighth of the retry's step).
_VALLEY_BISECTIONS = 3
_VALLEY_DEPTH = 6
# Valleys are looked for this far [m] beyond where the scans stopped.
_VALLEY_REACH = 0.02
# An end speed (T1, T2) the arc cannot take comes down by this factor, at most this often.
_END_RETRY_FACTOR = 0.8
_END_TRIES = 12
# ... and is then bisected this often between the lowest that failed and the one that serves
# (to 2.5 % of a retry's step: each bisection solves the whole arc again).
_END_BISECTIONS = 3
# A G2 end (curvature 0 at T1/T2) need not be entered at s'' = 0: the lift may still be
# braking there (and the descent start still speeding up), which the normal jerk
# kappa_s s'**3 + 3 kappa s' s'' allows (kappa is 0 there) and which spares the lift its last
# ramp of s'' back to 0, while the arc then starts slower. Entry accelerations tried, as
# shares of max_accel, the first kept unless another is faster: -0.2 does best of one to
# five values on seeded random pairs (scripts/join_study.py, study ``entry``).
_END_ACCEL_SHARES = (0.0, -0.2)
# Each is tried by a probe: the line's duration plus a scan from the end state over
# _PROBE_REACH of the horizon (_PROBE_HORIZON of the transition), the rest of the horizon at
# _PROBE_ACCEL of max_accel; each probe within _PROBE_STEPS of its own. On seeded random pairs
# the probes pick what whole plans pick (the choice costs ~10 % of a request's CPU time).
_PROBE_HORIZON = 0.5
_PROBE_REACH = 0.3
_PROBE_ACCEL = 0.8
_PROBE_STEPS = 400
# Stretches solved per plan before giving up on the scans (the fallback then serves).
_HILL_BUDGET = 40
# Scan steps per plan (both directions, every stretch and retry) before giving up on the
# scans likewise: a bound on the work, above the worst of 317 seeded random legs (7,867).
_STEP_BUDGET = 12000
# The sure but slow construction, when the scans find nothing: Ruckig pieces between knots.
_FALLBACK_PIECES = 24
# Steps both scans go on past their crossing, room for the piece that joins them: a few
# first (most joins need less than 10 ms), the rest only if the join fails with those.
_JOIN_ROOM_STEPS = 15
_JOIN_ROOM_MORE = 25
# A join that fails at the crossing is solved again with the other jerk sign and, where the
# crossing lies more than _VALLEY_REACH from both ends of the stretch, from up to this many
# forward scan states before it. Where both scans hold the speed limit, their s'' chatters
# from step to step (each step levels off anew): which state first tops the other scan is
# happenstance, and so are the s'' the solve starts from and the jerk sign they suggest; from
# there Newton may find only pieces of negative duration (bench request 373's approach), and
# no lower end speed helps (the scans are the same that far from the ends). A crossing near
# an end is left to the end's retries (a lower end speed), as before.
_JOIN_EARLIER = 3
# Bisections towards the edge of the backward scan's reach when the join's bracketing search
# jumped over it (2 ms / 2**30: below a nanosecond).
_JOIN_EDGE_STEPS = 30
# Share of the acceleration and jerk limits that cruising (s'' = 0) uses at the ceiling that
# places speed valleys.
_CEILING_SHARE = 0.9
# The speed cap along the arc is taken as stairs this many table cells long.
_CAP_STAIR = 8
# The cap's values where there is no cap (the array type the tables' kernel is compiled for).
_NO_CAP = np.empty(0)


class _EndTooFast(Exception):
    """The scan from T1 (``at_start``) or T2 gives up: that end's speed must come down."""

    def __init__(self, at_start):
        super().__init__()
        self.at_start = at_start


class _ArcPlanner:
    """The time-optimal construction on the arc: scans, joins and speed valleys."""

    def __init__(self, path, limits, speed_cap):
        bend = path.bend
        self.path, self.limits = path, limits
        self.length = float(path.segment_lengths[1])
        # Curvature on a fine grid of the curve parameter, resampled uniformly in s.
        # Cells no longer than the smallest radius of curvature (the arc may be a needle).
        intervals = int(min(_TABLE_INTERVALS_MAX, max(_TABLE_INTERVALS, 2 ** math.ceil(
            math.log2(self.length / bend.min_radius)))))
        kappa_t, kappa_s_t, sigma = bend.curvature_on_grid(2 * intervals + 1)[1:]
        grid = _even_samples(0.0, self.length, intervals + 1)
        # The speeds the lines aim at ({(s_from, s_to, cap): speed}): the probes solve the
        # lines to the end states they try, the chosen one is solved again for the motion.
        self._cap_speeds = {}
        values, stretches = _NO_CAP, ()
        if speed_cap is not None:
            values, stretches = self._cap_on_grid(speed_cap, grid)
        # The speed cap as stairs of _CAP_STAIR cells, each at the lowest value it spans: the
        # scans level off on a stair and cruise, and two scans cruising on one stair meet.
        forward, backward, lowest = _planner_tables(sigma, kappa_t, kappa_s_t, grid, values,
                                                    len(stretches))
        for (s_from, s_to), value in zip(stretches, lowest.tolist()):
            self._cap_speeds[s_from, s_to, speed_cap] = _capped_line_speed(limits, value)
        self.grid = grid
        self._grid_step = float(grid[1])
        cell = self.length / intervals
        budget = np.array([_STEP_BUDGET])
        self.forward = _Scanner(forward, cell, limits, budget)
        self.backward = _Scanner(backward, cell, limits, budget)
        # The speed, acceleration and jerk of the ceiling (see ceiling).
        self._cruise_limits = (limits.max_speed * _SPEED_MARGIN,
                               _CEILING_SHARE * limits.max_accel * _ACCEL_MARGIN,
                               _CEILING_SHARE * limits.max_jerk * _JERK_MARGIN)
        # A G2 join's ends have curvature 0 exactly (the table holds rounding there).
        self.kappa_end = ((0.0, 0.0) if path.join == 'g2'
                          else (float(forward[0, 0]), float(forward[0, -1])))
        self.hills = 0
        # The vertical lines solved so far by Ruckig ({arguments: rows}), for the same reason
        # as the speeds they aim at.
        self._lines = {}
        # The lengths [m] of the G2 transitions at T1 and T2 the probes look ahead over.
        self._transitions = {}

    @functools.cached_property
    def ceiling(self):
        """
        Return the speed ceiling at each grid point (:func:`_cruise_speeds`), computed once.

        It places the speed valleys and their speeds. Most arcs join without one (520 of 589
        bench legs): only their ends' are read then (:meth:`end_speed`), so the whole grid's
        (a hypot and a cube root at a fifth of its points) is computed where first needed.
        """
        return _cruise_speeds(self.forward.table, *self._cruise_limits)

    def _cap_on_grid(self, speed_cap, grid):
        """
        Return the speed cap's values on the arc's ``grid`` and the end speeds' line stretches.

        Returns (values, stretches): the cap at the grid points (path lengths), then at the
        ``_LIMIT_SAMPLES`` of each stretch [s_from, s_to] of ``stretches`` (a tuple of
        pairs) on which :meth:`end_speed` asks for the lines' speed (:func:`_line_speed`),
        all in one call of the cap. A cap that fails is asked again as those would ask it,
        one after the other, to name its first failure as they do.
        """
        c1, _, c2 = self.path.segment_lengths.tolist()
        length = self.path.length
        # end_speed's stretches, where _line_speed asks the cap (a line longer than nothing).
        stretches = tuple((start, start + clearance) for start, clearance
                          in ((0.0, c1), (length - c2, c2))
                          if clearance > 0.0 and start + clearance > start)
        queries = _cap_queries(c1, grid, np.array(stretches, dtype=float).reshape(-1, 2),
                               _LIMIT_SAMPLES)
        try:
            # A C-contiguous, writable copy: the one array type the kernel is compiled for (a
            # cap may answer with any view).
            return np.array(_cap_values(speed_cap, queries)), stretches
        except InvalidInputError:
            _cap_values(speed_cap, c1 + grid)
            for s_from, s_to in stretches:
                _line_speed(self.limits, speed_cap, s_from, s_to)
            raise

    def line_rows(self, start, end, speed_cap, s_start, s_end):
        """Return :func:`_line_rows` of a vertical line on the planner's limits, solved once."""
        # Exact keys, the floats' bytes: -0.0 (a mirrored rest acceleration) is not 0.0 to
        # Ruckig's last bit.
        key = _EIGHT_FLOATS.pack(*start, *end, s_start, s_end), speed_cap
        if key not in self._lines:
            self._lines[key] = _ruckig_rows(
                start, end, self._cap_speed(speed_cap, s_start, s_end),
                *_line_limits(self.limits))
        return self._lines[key]

    def _cap_speed(self, speed_cap, s_from, s_to):
        """Return :func:`_line_speed` on [s_from, s_to], asking the cap once per stretch."""
        key = s_from, s_to, speed_cap
        if key not in self._cap_speeds:
            self._cap_speeds[key] = _line_speed(self.limits, speed_cap, s_from, s_to)
        return self._cap_speeds[key]

    def end_speed(self, clearance, at_start, speed_cap):
        """Return the speed aimed at at T1 (``at_start``) or T2 (see :meth:`end_state`)."""
        limits = self.limits
        index = 0 if at_start else -1
        # A G2 join has no curvature at T1/T2, hence no acceleration step to bound.
        step_speed = (math.inf if self.kappa_end[index] <= 0.0 else
                      math.sqrt(limits.max_accel_jump / self.kappa_end[index]) * (1.0 - 1e-3))
        table = self.forward.table
        ceiling = _cruise_speed(table, 0 if at_start else table.shape[1] - 1,
                                *self._cruise_limits)
        speed = min(ceiling, step_speed,
                    _reach_speed(clearance, limits.max_accel * _ACCEL_MARGIN,
                                 limits.max_jerk * _JERK_MARGIN) * (1.0 - 1e-3))
        if speed_cap is not None and clearance > 0.0:
            # The ceiling is below the speed limit's margin already: only the cap counts here.
            start = 0.0 if at_start else self.path.length - clearance
            speed = min(speed, self._cap_speed(speed_cap, start, start + clearance))
        return speed

    def end_state(self, speed, clearance, at_start, speed_cap):
        """
        Return the state (s', s'') aimed at at T1 (``at_start``) or T2, in forward time.

        ``speed`` is :meth:`end_speed`'s. A paper join is entered at s'' = 0
        (its acceleration step is bounded at rest acceleration). A G2 end
        tries each of ``_END_ACCEL_SHARES`` (at T2 mirrored: the descent
        starts still speeding up) by :meth:`_probe` and keeps the fastest, the
        first unless another is strictly faster.
        """
        if self.path.join != 'g2' or speed <= 0.0 or clearance <= 0.0:
            return speed, 0.0
        accels = [share * self.limits.max_accel for share in _END_ACCEL_SHARES]
        best = accels[0]
        if len(accels) > 1:
            times = [self._probe(speed, accel, clearance, at_start, speed_cap)
                     for accel in accels]
            # The first of the fastest (min keeps the first of equals); all failing: the first.
            best = accels[min(range(len(accels)), key=times.__getitem__)]
        return (speed, best) if at_start else (speed, -best)

    def _probe(self, speed, accel, clearance, at_start, speed_cap):
        """
        Return the time the line and the arc's start take from an end state, or inf.

        The end state is (``speed``, ``accel``) in the scan's direction (from
        T2 backwards at T2): the vertical line to (from) it by Ruckig, then a
        scan from it over ``_PROBE_REACH`` of the horizon, on a scanner of its
        own (its back-ups must not lower the plan's targets), then the rest of
        the horizon from the scan's last speed at ``_PROBE_ACCEL`` of
        max_accel (a faster probe there is ahead). Inf where the line or the
        scan fails. A scan that took its steps without backing up (its shares
        all 1, as the plan's before its first scan) is the start of the arc's
        scan from that end state (the chosen one's; the one at s'' = 0 also
        where a chosen s'' != 0 fails): the scanner keeps it (:meth:`_Scanner.keep`).
        """
        path, limits = self.path, self.limits
        bend = path.bend
        if at_start:
            line = self.line_rows((0.0, 0.0, 0.0), (clearance, speed, accel), speed_cap,
                                  0.0, clearance)
            if at_start not in self._transitions:
                self._transitions[at_start] = float(bend.s_from_t(math.pi - bend.span_1))
            scanner = self.forward
        else:
            end = path.length - clearance
            line = self.line_rows((end, speed, -accel), (path.length, 0.0, 0.0), speed_cap,
                                  end, path.length)
            if at_start not in self._transitions:
                self._transitions[at_start] = self.length - float(bend.s_from_t(bend.span_2))
            scanner = self.backward
        if line is None:
            return math.inf
        horizon = min(_PROBE_HORIZON * self._transitions[at_start], 0.5 * self.length)
        reach = _PROBE_REACH * horizon
        reached, time, last, states, info = _probe_scan(
            scanner.table, scanner.constants, float(speed), float(accel), reach, _PROBE_STEPS)
        if info[_FAILURES] == 0:
            scanner.keep(states, info)
        if not reached:
            return math.inf
        rest_accel = _PROBE_ACCEL * limits.max_accel
        rest = (math.sqrt(last * last + 2.0 * rest_accel * (horizon - reach)) - last) / rest_accel
        return _rows_duration(line) + time + rest

    def solve(self, entry, exit_state):
        """
        Return (arc rows, entry (s', s''), exit (s', s'')) from T1 to T2.

        ``entry`` and ``exit_state`` are the states aimed at (:meth:`end_state`).
        An end state the arc cannot take (the curvature grows too fast just
        inside it) first drops its s'' to 0, then its speed comes down by
        ``_END_RETRY_FACTOR`` until it can; each end speed that came down is
        then bisected ``_END_BISECTIONS`` times between the lowest that failed
        and the one that serves. A faster end does not always make a faster
        arc (it may need a lower valley further in): a trial is kept only if
        its arc is not slower (the line to a faster end is not slower either).
        Bisections stop once half the step or hill budget is spent: they
        refine, the rest is kept for the retries.
        """
        states, failed = [tuple(entry), tuple(exit_state)], [None, None]
        for _ in range(_END_TRIES):
            try:
                solved = self._arc(states)
                break
            except _EndTooFast as trouble:
                end = 0 if trouble.at_start else 1
                speed, accel = states[end]
                if accel == 0.0:
                    failed[end] = speed
                    speed *= _END_RETRY_FACTOR
                states[end] = (speed, 0.0)
        else:
            raise _NoMotion()
        try:
            for _ in range(_END_BISECTIONS):
                for end in (0, 1):
                    if failed[end] is None or self._half_spent():
                        continue
                    trial = list(states)
                    trial[end] = (0.5 * (states[end][0] + failed[end]), 0.0)
                    try:
                        found = self._arc(trial)
                    except _EndTooFast:
                        failed[end] = trial[end][0]
                        continue
                    if _rows_duration(found[0]) <= _rows_duration(solved[0]):
                        solved, states = found, trial
                    else:
                        failed[end] = trial[end][0]
        except _NoMotion:
            # The hill or step budget is spent: keep the motion found.
            pass
        return solved

    def _half_spent(self):
        """Return whether half the step budget or half the hill budget is spent."""
        return (self.forward.budget[0] < _STEP_BUDGET // 2
                or self.hills >= _HILL_BUDGET // 2)

    def _arc(self, states):
        """Solve the whole arc from T1 in states[0] to T2 in states[1] ((s', s'') each)."""
        return self._hill(0.0, states[0], self.length, states[1], True, True, 0)

    def _hill(self, s_a, state_a, s_b, state_b, free_a, free_b, depth):
        """
        Solve [s_a, s_b] from state_a to state_b ((s', s'') each).

        A free end (T1, T2) may end at a lower state when the other scan
        never comes down to it (the clearance then adapts); a fixed end (a
        speed valley) may not.
        """
        self.hills += 1
        if self.hills > _HILL_BUDGET:
            raise _NoMotion()
        length = self.length
        forward = self.forward.scan(s_a, state_a[0], state_a[1], s_b)
        backward = self.backward.scan(length - s_b, state_b[0], -state_b[1], length - s_a)
        scanners = self.forward.parts(), self.backward.parts()
        if _scan_both(*scanners, forward.parts(), backward.parts(), length, True,
                      _JOIN_ROOM_STEPS) == _OUT_OF_STEPS:
            raise _NoMotion()
        joined = self._join(forward, backward)
        # Scans that both stopped take no more step (nor spend the budget): the join would
        # fail as it did.
        if joined is None and (forward.info[_STATUS] == _LIVE
                               or backward.info[_STATUS] == _LIVE):
            counts = forward.count, backward.count
            if _scan_both(*scanners, forward.parts(), backward.parts(), length, False,
                          _JOIN_ROOM_MORE) == _OUT_OF_STEPS:
                raise _NoMotion()
            # A scan that stopped took no step (the join would fail as it did).
            if (forward.count, backward.count) != counts:
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
        index = _valley_index(self.ceiling, self._grid_step, forward.states, forward.count,
                              backward.states, backward.count, length, s_a, s_b)
        if index >= 0 and depth < _VALLEY_DEPTH:
            # The scans are done with here: the parts' scanners hand them out again (the left
            # part's from s_a, the right part's from s_b; see _Scanner.scan).
            return self._split(index, s_a, state_a, s_b, state_b, free_a, free_b, depth)
        # No valley in between: a scan from a free end that gives up started too fast.
        failed_a = forward.status != 'end' and free_a
        failed_b = backward.status != 'end' and free_b
        if failed_a and failed_b:
            failed_a = forward.last()[1] - s_a < backward.last()[1] - (length - s_b)
            failed_b = not failed_a
        if failed_a or failed_b:
            raise _EndTooFast(failed_a)
        raise _NoMotion()

    def _split(self, index, s_a, state_a, s_b, state_b, free_a, free_b, depth):
        """
        Solve [s_a, s_b] as two parts meeting at rest acceleration in valley ``index``.

        The valley speed starts at ``_VALLEY_SHARE`` of the ceiling there and
        comes down by ``_VALLEY_RETRY_FACTOR`` until both parts are solved; if it
        came down, it is bisected ``_VALLEY_BISECTIONS`` times between the
        lowest failure and the success, a trial kept only if it is not slower
        (while less than half the step and hill budgets is spent).
        """
        def parts(speed):
            valley = (speed, 0.0)
            left, entry, _ = self._hill(s_a, state_a, s_v, valley, free_a, False, depth + 1)
            right, _, exit_state = self._hill(s_v, valley, s_b, state_b, False, free_b,
                                              depth + 1)
            return np.concatenate((left, right)), entry, exit_state

        s_v = float(self.grid[index])
        speed, failed = float(self.ceiling[index]) * _VALLEY_SHARE, None
        for _ in range(_VALLEY_TRIES):
            try:
                solved = parts(speed)
                break
            except _NoMotion:
                failed, speed = speed, speed * _VALLEY_RETRY_FACTOR
        else:
            raise _NoMotion()
        for _ in range(_VALLEY_BISECTIONS if failed is not None else 0):
            if self._half_spent():
                break
            trial = 0.5 * (speed + failed)
            try:
                found = parts(trial)
            except (_NoMotion, _EndTooFast):
                # A trial refines what was solved: its failures never undo that.
                failed = trial
                continue
            if _rows_duration(found[0]) <= _rows_duration(solved[0]):
                solved, speed = found, trial
            else:
                failed = trial
        return solved

    def _join(self, forward, backward):
        """Return the rows forward scan -> one piece -> backward scan (see :func:`_join`)."""
        joined, rows = _join(self.forward.parts(), forward.parts(), backward.parts(),
                             self.length)
        return rows if joined else None

    def fallback(self, v_in, v_out):
        """
        Return (rows, entry, exit) of a slower but sure motion along the arc.

        Ruckig pieces between ``_FALLBACK_PIECES`` + 1 knots, at rest
        acceleration at each knot, with constant limits that hold on the
        piece's stretch (:func:`_constant_limits`); knot speeds start at half
        the ceiling around them and come down where a piece does not fit.
        """
        knots = np.linspace(0.0, self.length, _FALLBACK_PIECES + 1)
        cells = np.minimum((knots / self.grid[1]).astype(int), self.grid.size - 1)
        speeds = [0.5 * float(self.ceiling[cells[max(index - 1, 0)]:
                                           cells[min(index + 1, _FALLBACK_PIECES)] + 1].min())
                  for index in range(_FALLBACK_PIECES + 1)]
        speeds[0], speeds[-1] = min(speeds[0], v_in), min(speeds[-1], v_out)
        offset = float(self.path.segment_lengths[0])
        pieces = [None] * _FALLBACK_PIECES
        index, budget = 0, 20 * _FALLBACK_PIECES
        while index < _FALLBACK_PIECES:
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
        rows = np.array([row for piece in pieces for row in piece])
        return rows, (speeds[0], 0.0), (speeds[-1], 0.0)


@kernel
def _probe_scan(table, constants, speed, accel, reach, steps):
    """
    Return (reached, time [s], s' there, states, info) of a probe's scan from (0, speed, accel).

    On the ``table`` and ``constants`` of one of the plan's scanners, with back-up shares
    and a budget of ``steps`` of its own (its back-ups must not lower the plan's targets);
    reached is False where it stops before ``reach`` [m] or runs out of steps. ``states``
    and ``info`` are the scan's (see arc_scan's layouts).
    """
    factor = np.ones(table.shape[1] + 1)
    budget = np.full(1, steps)
    states, info, floats = _new_scan(0.0, speed, accel, reach, steps + 2)
    if _run((table, constants, factor, budget), (states, info, floats)) == _OUT_OF_STEPS or (
            info[_STATUS] != _END):
        return False, 0.0, 0.0, states, info
    count = info[_COUNT]
    time = _time_at(states, count, reach)
    return True, time, _state(states, count, time)[1], states, info


@kernel
def _valley_index(ceiling, grid_step, forward, forward_count, backward, backward_count,
                  length, s_a, s_b):
    """
    Return the grid index of the lowest ceiling between where the scans stopped, or -1.

    Only a true valley counts: lower than the ``ceiling`` (M,) at both ends
    of the stretch searched, which reaches ``_VALLEY_REACH`` beyond the
    scans' ends (``forward`` and ``backward`` hold the scans' states, the
    first ``*_count``) and stays 4 grid steps [m] inside [s_a, s_b].
    Of equal lowest values the first (``numpy.argmin``'s choice).
    """
    margin = 4 * grid_step
    end_a, end_b = forward[1, forward_count - 1], length - backward[1, backward_count - 1]
    if end_b < end_a:
        end_a, end_b = end_b, end_a
    low = int(_py_max(end_a - _VALLEY_REACH, s_a + margin) / grid_step)
    high = int(_py_min(end_b + _VALLEY_REACH, s_b - margin) / grid_step) + 1
    if high - low < 3:
        return -1
    index = low
    for here in range(low + 1, high):
        if ceiling[index] != ceiling[index]:
            break
        if ceiling[here] < ceiling[index] or ceiling[here] != ceiling[here]:
            index = here
    lowest = ceiling[index]
    if lowest < ceiling[low] * (1.0 - 1e-9) and lowest < ceiling[high - 1] * (1.0 - 1e-9):
        return index
    return -1


@kernel
def _cap_queries(offset, grid, stretches, samples):
    """
    Return the path lengths [m] at which the planner asks the speed cap (see _cap_on_grid).

    ``offset`` + the arc's ``grid`` (M,), then ``samples`` even samples
    (:func:`~ellipath_ros.core.limits._even_samples`) of each stretch of ``stretches``
    (S, 2), rows (s_from, s_to).
    """
    points = grid.size
    queries = np.empty(points + stretches.shape[0] * samples)
    for index in range(points):
        queries[index] = offset + grid[index]
    for stretch in range(stretches.shape[0]):
        first = points + stretch * samples
        queries[first:first + samples] = _even_samples(stretches[stretch, 0],
                                                       stretches[stretch, 1], samples)
    return queries


@kernel
def _planner_tables(sigma, kappa_t, kappa_s_t, grid, cap, stretches):
    """
    Return the :class:`_ArcPlanner`'s scan tables and lowest caps: (forward, backward, lowest).

    The curvature resampled evenly on the arc's ``grid`` (M,) (:func:`_uniform_curvature` of
    ``sigma``, ``kappa_t``, ``kappa_s_t``), the speed cap's stairs (:func:`_cap_stairs` of its
    values at the grid points, ``cap``'s first M; none where ``cap`` is empty), in the scans'
    tables (:func:`~ellipath_ros.core.arc_scan._arc_tables`): one call for the steps that
    each cost a call. ``lowest`` (S,) holds the lowest cap on each of the ``stretches`` line
    stretches whose values follow the grid's in ``cap`` (``_LIMIT_SAMPLES`` each).
    """
    points = grid.size
    forward, backward = np.empty((5, points)), np.empty((5, points))
    _uniform_curvature(sigma, kappa_t, kappa_s_t, grid, forward[0], forward[2])
    cells = forward[4, :points - 1]
    cells[:] = math.inf
    if cap.size:
        _cap_stairs(cap[:points], _SPEED_MARGIN, _CAP_STAIR, cells)
    _arc_tables(forward, backward)
    lowest = np.empty(stretches)
    for stretch in range(stretches):
        first = points + stretch * _LIMIT_SAMPLES
        lowest[stretch] = cap[first:first + _LIMIT_SAMPLES].min()
    return forward, backward, lowest


@kernel
def _uniform_curvature(sigma, kappa_t, kappa_s_t, grid, kappa, kappa_s):
    """
    Fill ``kappa`` and ``kappa_s`` (M,) at the arc lengths ``grid`` (M,), even steps from 0.

    ``sigma``, ``kappa_t`` and ``kappa_s_t`` (2 K + 1,) are the curve's speed
    |dQ/dt|, curvature and its rate at even steps of t from pi to 0: the arc
    length there by Simpson's rule on pairs of steps (linear between a pair's
    ends at its middle), scaled to end at ``grid[-1]``, then the curvature and
    its rate interpolated linearly at ``grid`` (as ``numpy.interp``). The bend
    never turns the other way: a G2 end's 0 that rounds to -1e-14 is 0.
    """
    count = sigma.size
    lengths = np.empty(count)
    lengths[0] = 0.0
    total, width = 0.0, math.pi / count
    for pair in range(count // 2):
        index = 2 * pair
        total += (sigma[index] + 4.0 * sigma[index + 1] + sigma[index + 2]) * width
        lengths[index + 2] = total / 3.0 * 2.0
        lengths[index + 1] = (lengths[index + 2] - lengths[index]) / 2.0 + lengths[index]
    scale = grid[grid.size - 1] / lengths[count - 1]
    for index in range(count):
        lengths[index] *= scale
    below = 0
    for row in range(grid.size):
        here = grid[row]
        while below < count - 2 and lengths[below + 1] <= here:
            below += 1
        if here >= lengths[count - 1]:
            kappa[row], kappa_s[row] = max(kappa_t[count - 1], 0.0), kappa_s_t[count - 1]
            continue
        step = lengths[below + 1] - lengths[below]
        offset = here - lengths[below]
        kappa[row] = max((kappa_t[below + 1] - kappa_t[below]) / step * offset
                         + kappa_t[below], 0.0)
        kappa_s[row] = ((kappa_s_t[below + 1] - kappa_s_t[below]) / step * offset
                        + kappa_s_t[below])


@kernel
def _cap_stairs(values, margin, stair, cells):
    """
    Fill ``cells`` (M - 1,) with the speed cap as stairs of ``stair`` cells (M - 1 a multiple).

    Each stair is ``margin`` times the lowest of the cap ``values`` (M,) at
    the grid points its cells span (both ends of each); the values are
    positive and finite (:func:`~ellipath_ros.core.limits._cap_values`).
    """
    for first in range(0, cells.size, stair):
        lowest = margin * values[first]
        for index in range(first + 1, first + stair + 1):
            lowest = _py_min(lowest, margin * values[index])
        cells[first:first + stair] = lowest


@kernel
def _cruise_speeds(table, speed, accel, jerk):
    """Return :func:`_cruise_speed` at each grid point of a scan ``table``, shape (M,)."""
    ceiling = np.empty(table.shape[1])
    for row in range(ceiling.size):
        ceiling[row] = _cruise_speed(table, row, speed, accel, jerk)
    return ceiling


@kernel(inline=True)
def _cruise_speed(table, row, speed, accel, jerk):
    """
    Return the speed at grid point ``row`` of a scan ``table`` at which s'' = 0 keeps the limits.

    The smallest of ``speed``, the cap of the cells on both sides,
    sqrt(``accel`` / kappa) and (``jerk`` / hypot(kappa**2, kappa_s))**(1/3)
    (no bound where the curvature, or both terms, are 0).
    """
    kappa, kappa_s = table[0, row], table[2, row]
    ceiling = min(speed, table[4, max(row - 1, 0)], table[4, min(row, table.shape[1] - 2)])
    if kappa > 0.0:
        ceiling = min(ceiling, math.sqrt(accel / kappa))
    # The jerk's bound is at least (jerk / (kappa**2 + |kappa_s|))**(1/3) (the sum is at least
    # the hypot): where that is above the ceiling by far more than rounding, the bound cannot
    # lower it, and its hypot and cube root (most of the time) are skipped. Otherwise (and
    # where both terms are 0: no bound) as described.
    if jerk < ceiling * ceiling * ceiling * (kappa ** 2 + abs(kappa_s)) * (1.0 + 1e-9):
        rate = math.hypot(kappa ** 2, kappa_s)
        if rate > 0.0:
            ceiling = min(ceiling, (jerk / rate) ** (1.0 / 3.0))
    return ceiling


def _optimal_motion(path, limits, speed_cap):
    """Build the time-optimal profile (see :func:`time_motion`)."""
    if path.arc is None:
        return _straight_motion(path, limits, speed_cap, 'time_optimal')
    # Python floats (as the lines' keys hold them), one conversion for the three.
    c1, arc_length, c2 = path.segment_lengths.tolist()
    planner = _ArcPlanner(path, limits, speed_cap)
    entry = planner.end_state(planner.end_speed(c1, True, speed_cap), c1, True, speed_cap)
    exit_state = planner.end_state(planner.end_speed(c2, False, speed_cap), c2, False,
                                   speed_cap)
    parts = None
    for _ in range(_END_TRIES):
        try:
            arc = planner.solve(entry, exit_state)
        except _NoMotion:
            break
        parts = _with_lines(planner, speed_cap, *arc)
        if parts is not None:
            break
        # A line cannot reach the arc's entry (exit) state: ask for a slower one at rest
        # acceleration.
        if _with_lines(planner, speed_cap, arc[0], arc[1], (0.0, 0.0)) is None:
            entry = (_END_RETRY_FACTOR * min(entry[0], arc[1][0]), 0.0)
        else:
            exit_state = (_END_RETRY_FACTOR * min(exit_state[0], arc[2][0]), 0.0)
    if parts is None:
        parts = _with_lines(planner, speed_cap,
                            *planner.fallback(entry[0], exit_state[0]))
    if parts is None:
        raise LimitError('time-optimal profile: expected vertical segments that reach the '
                         'arc within the limits, got none')
    lift, arc_rows, descent, entry, exit_state = parts
    pieces = _PieceList()
    pieces.extend(lift)
    pieces.extend(arc_rows, c1)
    pieces.extend(descent)
    law = pieces.law()
    # The arc's time is what the lines leave of the law's.
    lift_time, descent_time = _rows_duration(lift), _rows_duration(descent)
    segments = np.array([lift_time, law.duration - lift_time - descent_time, descent_time])
    return TimedMotion(path, 'time_optimal', law.duration, segments,
                       entry[0] ** 2 * planner.kappa_end[0],
                       exit_state[0] ** 2 * planner.kappa_end[1], None, law)


def _with_lines(planner, speed_cap, arc_rows, entry, exit_state):
    """Return (lift rows, arc rows, descent rows, entry, exit), or None if a line fails."""
    path = planner.path
    c1, arc_length, _ = path.segment_lengths.tolist()
    lift, descent = [], []
    if c1 > 0.0:
        lift = planner.line_rows((0.0, 0.0, 0.0), (c1, entry[0], entry[1]), speed_cap, 0.0, c1)
    elif entry[0] > 0.0 or entry[1] != 0.0:
        lift = None
    end = c1 + arc_length
    if path.length > end:
        descent = planner.line_rows((end, exit_state[0], exit_state[1]),
                                    (path.length, 0.0, 0.0), speed_cap, end, path.length)
    elif exit_state[0] > 0.0 or exit_state[1] != 0.0:
        descent = None
    if lift is None or descent is None:
        return None
    return lift, arc_rows, descent, entry, exit_state


# -- the kernels that run the scans (see arc_scan's layouts) ----------------------------------

@kernel(zero_divisions=False)
def _scan_both(forward_scanner, backward_scanner, forward, backward, length, search, room):
    """
    Advance the slower of the two scans until their speed curves cross, then ``room`` more.

    Both scans speed up away from their start, so the crossing lies where the
    slower one catches up; neither needs to run past it but for the room the
    join needs (see :func:`_add_room`; without ``search``, only that room is
    added). Returns _STOPPED, or _OUT_OF_STEPS once the budget is spent.
    ``length`` [m] is the arc's. (One kernel for both uses: each kernel
    Python calls is compiled, or loaded from the cache, on its own.)
    """
    # Unpacked once: a kernel's array variables cost reference counting where they are made.
    forward_table, forward_constants, forward_factor, forward_budget = forward_scanner
    backward_table, backward_constants, backward_factor, backward_budget = backward_scanner
    forward_states, forward_info, forward_floats = forward
    backward_states, backward_info, backward_floats = backward
    while search and (forward_info[_STATUS] == _LIVE or backward_info[_STATUS] == _LIVE):
        if forward_info[_STATUS] == _LIVE and (
                backward_info[_STATUS] != _LIVE
                or forward_states[2, forward_info[_COUNT] - 1]
                <= backward_states[2, backward_info[_COUNT] - 1]):
            done = _advance(forward_table, forward_constants, forward_factor, forward_budget,
                            forward_states, forward_info, forward_floats, True)
            crossed = done == _ADVANCED and _tops(forward_states, forward_info[_COUNT],
                                                  backward_states, backward_info[_COUNT],
                                                  length)
        else:
            done = _advance(backward_table, backward_constants, backward_factor,
                            backward_budget, backward_states, backward_info, backward_floats,
                            True)
            crossed = done == _ADVANCED and _tops(backward_states, backward_info[_COUNT],
                                                  forward_states, forward_info[_COUNT], length)
        if done == _OUT_OF_STEPS:
            return done
        if crossed:
            break
    return _add_room(forward_scanner, backward_scanner, forward, backward, room)


@kernel
def _join(scanner, forward, backward, length):
    """
    Return (joined, rows): forward scan -> one constant-jerk piece -> backward scan.

    The piece starts at time x of the forward scan, ends at time y of the
    backward one and has jerk j: s, s', s'' must match at both ends, three
    equations in x, y and the piece's duration (see :func:`_solve_join`),
    with the largest jerk the piece keeps legal (:func:`_piece_check`).
    Where both scans cruise at the same speed, they are simply switched.
    The solve starts at the crossing with the jerk sign that brings the
    forward scan's s'' there to the backward one's, then the other sign;
    at a crossing inside the stretch (see ``_JOIN_EARLIER``) from up to
    ``_JOIN_EARLIER`` forward states before it too.
    ``rows``, shape (pieces, 5), as :func:`~ellipath_ros.core.arc_scan._rows`
    gives them (none if not joined); ``scanner`` is the forward one.
    """
    forward_states, forward_count = forward[0], forward[1][_COUNT]
    backward_states, backward_count = backward[0], backward[1][_COUNT]
    index, cruising = _crossing(forward_states, forward_count, backward_states,
                                backward_count, length)
    if index < 0:
        return False, np.empty((0, 5))
    s_c = forward_states[1, index]
    if cruising:
        y_c = _time_at(backward_states, backward_count, length - s_c)
        return True, _joined_rows(
            _rows(forward_states, forward_count, forward_states[0, index]), np.empty((0, 5)),
            _reversed_rows(backward_states, backward_count, y_c, length))
    # The stretch's ends: where the scans started.
    inside = (s_c - forward_states[1, 0] > _VALLEY_REACH
              and length - backward_states[1, 0] - s_c > _VALLEY_REACH)
    earliest = max(index - _JOIN_EARLIER, 0) if inside else index
    for start in range(index, earliest - 1, -1):
        for preferred in (True, False):
            joined, rows = _join_from(scanner, forward, backward, length, start, preferred)
            if joined:
                return True, rows
    return False, np.empty((0, 5))


@kernel
def _join_from(scanner, forward, backward, length, index, preferred):
    """
    Return (joined, rows) of :func:`_join` solved from the forward scan's state ``index``.

    The jerk starts at 99 % of the end of the legal range at that state
    that brings the forward scan's s'' to the backward one's at the same
    place (``preferred``), or of the other end, and comes down to what
    :func:`_piece_check` finds legal (5 tries).
    """
    table, constants = scanner[0], scanner[1]
    forward_states, forward_count = forward[0], forward[1][_COUNT]
    backward_states, backward_count = backward[0], backward[1][_COUNT]
    none = np.empty((0, 5))
    x_c, s_c = forward_states[0, index], forward_states[1, index]
    y_c = _time_at(backward_states, backward_count, length - s_c)
    a_f = _state(forward_states, forward_count, x_c)[2]
    a_b = -_state(backward_states, backward_count, y_c)[2]
    found, lowest, highest = _jerk_range(table, constants, s_c, forward_states[2, index], a_f)
    if not found:
        return False, none
    jerk = 0.99 * (lowest if (a_b < a_f) == preferred else highest)
    for _ in range(5):
        solved, x, y, duration = _solve_join(
            (forward_states, forward_count, backward_states, backward_count, length, jerk),
            x_c, y_c)
        if not solved:
            return False, none
        s, v, a = _state(forward_states, forward_count, x)
        legal, worst = _piece_check(table, constants, s, v, a, duration, jerk)
        if not legal:
            return False, none
        if worst == jerk:
            piece = np.empty((1, 5))
            piece[0, 0], piece[0, 1], piece[0, 2], piece[0, 3], piece[0, 4] = (
                duration, s, v, a, jerk)
            return True, _joined_rows(
                _rows(forward_states, forward_count, x), piece,
                _reversed_rows(backward_states, backward_count, y, length))
        jerk = 0.99 * worst
    return False, none


@kernel
def _joined_rows(head, middle, tail):
    """Return the rows (pieces, 5) of ``head``, ``middle`` and ``tail`` one after the other."""
    rows = np.empty((head.shape[0] + middle.shape[0] + tail.shape[0], 5))
    rows[:head.shape[0]] = head
    rows[head.shape[0]:head.shape[0] + middle.shape[0]] = middle
    rows[head.shape[0] + middle.shape[0]:] = tail
    return rows


@kernel(inline=True)
def _tops(states, count, other, other_count, length):
    """
    Return whether a scan's last state tops the other scan (its speed at the same place).

    ``states`` and ``other`` hold the scans' states (the first ``count`` and
    ``other_count``). The speed curves cannot cross before the scans overlap.
    """
    last = count - 1
    if length - states[1, last] < other[1, other_count - 1]:
        found, speed = _speed_at(other, other_count, length - states[1, last])
        return found and states[2, last] >= speed * (1.0 - 1e-12)
    return False


@kernel(zero_divisions=False)
def _add_room(forward_scanner, backward_scanner, forward, backward, steps):
    """Advance both scans ``steps`` past their crossing (no backing up past it)."""
    forward_table, forward_constants, forward_factor, forward_budget = forward_scanner
    backward_table, backward_constants, backward_factor, backward_budget = backward_scanner
    forward_states, forward_info, forward_floats = forward
    backward_states, backward_info, backward_floats = backward
    for _ in range(steps):
        # Both steps, then their results: a branch on the first right behind it would split
        # that inlined step's end, and numba's reference counting of its arrays would stay
        # (see arc_scan's _held). Past the budget's end the backward step changes at most the
        # budget and that scan's status, which nothing reads: the plan gives up on the scans.
        forward_done = _advance(forward_table, forward_constants, forward_factor,
                                forward_budget, forward_states, forward_info, forward_floats,
                                False)
        backward_done = _advance(backward_table, backward_constants, backward_factor,
                                 backward_budget, backward_states, backward_info,
                                 backward_floats, False)
        if forward_done == _OUT_OF_STEPS or backward_done == _OUT_OF_STEPS:
            return _OUT_OF_STEPS
    return _STOPPED


@kernel
def _crossing(forward, forward_count, backward, backward_count, length):
    """
    Return (forward index, both cruising) where the forward scan first tops the backward.

    ``forward`` and ``backward`` are the scans' states (shape (6, capacity),
    the first ``*_count`` filled); the index is -1 where they do not cross.
    """
    sigma = backward[1]
    started = False
    for index in range(forward_count):
        s = forward[1, index]
        position = _bisect_right(sigma, backward_count, length - s)
        if position == 0 or position >= backward_count:
            continue
        x = (length - s - sigma[position - 1]) / (sigma[position] - sigma[position - 1])
        v_b = backward[2, position - 1] + x * (backward[2, position] - backward[2, position - 1])
        difference = forward[2, index] - v_b
        if (abs(difference) <= 1e-9 * v_b and index < forward_count - 1
                and forward[4, index] == 0.0 and forward[3, index] == 0.0
                and backward[3, position] == 0.0 and backward[3, position - 1] == 0.0):
            return index, True
        if difference > 1e-12 and started:
            return index, False
        started = True
    return -1, False


@kernel
def _piece_check(table, constants, s, v, a, duration, jerk):
    """
    Check a constant-jerk piece from (s, s', s'') against the limits at 9 points.

    Returns (legal, jerk): ``jerk`` [m/s**3] if it is legal all along, the
    most aggressive legal value otherwise (same sign, smaller); legal is False
    if no jerk can serve. The points are ``numpy.linspace(0, duration, 9)``'s,
    computed as it does.
    """
    speed = constants[_SPEED_TARGET]
    accel_bound = constants[_ACCEL_SQUARED] * (1.0 + 1e-6)
    step = duration / 8
    worst = jerk
    for point in range(9):
        if point == 8:
            x = duration
        elif step == 0.0:
            x = point / 8 * duration + 0.0
        else:
            x = point * step + 0.0
        s1 = s + x * (v + x * (a / 2.0 + x * jerk / 6.0))
        v1, a1 = v + x * (a + x * jerk / 2.0), a + x * jerk
        kappa, _, cap = _table_at(table, constants[_CELL], s1)
        found, lowest, highest = _jerk_range(table, constants, s1, v1, a1)
        if (not found or v1 < -1e-9 or v1 > _py_min(cap, speed) * (1.0 + 1e-9)
                or a1 * a1 + math.pow(kappa * v1 * v1, constants[_TWO]) > accel_bound):
            return False, 0.0
        worst = _py_max(worst, lowest) if jerk < 0.0 else _py_min(worst, highest)
    return worst * jerk > 0.0, worst


@kernel
def _join_residual(problem, x, y):
    """
    Return (s' mismatch, s mismatch, duration) of the join piece from x to y.

    ``problem`` is (forward states, their count, backward states, their count,
    arc length [m], the piece's jerk [m/s**3]); the piece starts at time x [s]
    of the forward scan with that jerk and lasts until its s'' is the backward
    scan's at its time y [s].
    """
    forward, forward_count, backward, backward_count, length, jerk = problem
    s_f, v_f, a_f = _state(forward, forward_count, x)
    s_b, v_b, a_b = _state(backward, backward_count, y)
    s_b, a_b = length - s_b, -a_b
    tau = (a_b - a_f) / jerk
    return (v_f + tau * (a_f + tau * jerk / 2.0) - v_b,
            s_f + tau * (v_f + tau * (a_f / 2.0 + tau * jerk / 6.0)) - s_b, tau)


@kernel
def _solve_join(problem, x, y):
    """
    Solve the join for (solved, x, y, duration) near the crossing (x, y) [s].

    Newton on (x, y) for s and s' continuity (see :func:`_join_residual`);
    where it stalls (a scan's kinks: levelling off, cruising), brackets
    instead: y for s continuity at each x (:func:`_y_for`), then x for s'
    continuity. ``solved`` is False where neither finds a piece of duration
    >= 0.
    """
    forward, forward_count, backward, backward_count = problem[:4]
    x_max, y_max = forward[0, forward_count - 1], backward[0, backward_count - 1]
    x_c = x
    tau0 = _py_max(_join_residual(problem, x, y)[2], 0.0)
    x = _py_min(_py_max(x - tau0 / 2.0, 0.0), x_max)
    y = _py_min(_py_max(y - tau0 / 2.0, 0.0), y_max)
    delta = 1e-7
    for _ in range(40):
        e_v, e_s, tau = _join_residual(problem, x, y)
        if abs(e_v) < 1e-10 and abs(e_s) < 1e-12:
            return tau >= 0.0, x, y, tau
        dv_x, ds_x = _join_residual(problem, x + delta, y)[:2]
        dv_y, ds_y = _join_residual(problem, x, y + delta)[:2]
        j11, j12 = (dv_x - e_v) / delta, (dv_y - e_v) / delta
        j21, j22 = (ds_x - e_s) / delta, (ds_y - e_s) / delta
        det = j11 * j22 - j12 * j21
        if det == 0.0:
            return False, x, y, 0.0
        step_x = (j22 * e_v - j12 * e_s) / det
        step_y = (j11 * e_s - j21 * e_v) / det
        # Damped: a few milliseconds at most per iteration.
        scale = _py_min(1.0, 0.005 / _py_max(_py_max(abs(step_x), abs(step_y)), 1e-300))
        x = _py_min(_py_max(x - scale * step_x, 0.0), x_max)
        y = _py_min(_py_max(y - scale * step_y, 0.0), y_max)

    low, step = x_c, 0.002
    found, end = _y_for(problem, x_c, y_max)[::2]
    if not found:
        return False, x, y, 0.0
    # The smallest x with a y found before the first without one, and that one.
    inside, outside, beyond = x_c, 0.0, False
    while True:
        low = _py_max(low - step, 0.0)
        found, start = _y_for(problem, low, y_max)[::2]
        if found and start * end <= 0.0:
            break
        if not found:
            if not beyond:
                outside, beyond = low, True
        elif not beyond:
            inside = low
        if low <= 0.0:
            if not beyond:
                return False, x, y, 0.0
            found, low = _edge_bracket(problem, y_max, end, inside, outside)
            if not found:
                return False, x, y, 0.0
            break
        step *= 2.0
    found, x = _x_for(problem, y_max, low, x_c)
    if found:
        found, y = _y_for(problem, x, y_max)[:2]
    if not found:
        return False, x, y, 0.0
    tau = _join_residual(problem, x, y)[2]
    return tau >= 0.0, x, y, tau


@kernel
def _edge_bracket(problem, y_max, end, inside, outside):
    """
    Return (found, x): an x in (outside, inside] where s' continuity changes sign from ``end``.

    The doubling steps of the search may jump from an x whose piece ends
    within the backward scan to one beyond it (no y), over the stretch in
    between where the sign changes (a backward scan that stopped right at
    the crossing): bisect towards that edge.
    """
    for _ in range(_JOIN_EDGE_STEPS):
        middle = 0.5 * (outside + inside)
        found, mismatch = _y_for(problem, middle, y_max)[::2]
        if not found:
            outside = middle
        elif mismatch * end <= 0.0:
            return True, middle
        else:
            inside = middle
    return False, 0.0


@kernel
def _y_for(problem, x, y_max):
    """
    Return (found, y, s' mismatch there): the y in [0, y_max] where s is continuous at x.

    A root of the s mismatch of :func:`_join_residual` by the Illinois
    method (to 1e-13 s); found is False without a sign change or where it is
    not finite.
    """
    low, high = 0.0, y_max
    f_low, f_high = _join_residual(problem, x, low)[1], _join_residual(problem, x, high)[1]
    if not (f_low * f_high <= 0.0):
        return False, 0.0, 0.0
    side = 0
    for _ in range(100):
        if high - low <= 1e-13 or f_low == f_high:
            break
        middle = (low * f_high - high * f_low) / (f_high - f_low)
        f_middle = _join_residual(problem, x, middle)[1]
        if not math.isfinite(f_middle):
            return False, 0.0, 0.0
        low, high, f_low, f_high, side, root = _illinois(
            low, high, f_low, f_high, side, middle, f_middle)
        if root:
            return True, middle, _join_residual(problem, x, middle)[0]
    y = low if abs(f_low) <= abs(f_high) else high
    return True, y, _join_residual(problem, x, y)[0]


@kernel
def _x_for(problem, y_max, low, high):
    """
    Return (found, x): the x in [low, high] where s' is continuous (with s, see :func:`_y_for`).

    The Illinois method to 1e-11 s; found is False without a sign change,
    or where no y exists or the mismatch is not finite at a trial x.
    """
    found_low, f_low = _y_for(problem, low, y_max)[::2]
    found_high, f_high = _y_for(problem, high, y_max)[::2]
    if not (found_low and found_high and f_low * f_high <= 0.0):
        return False, 0.0
    side = 0
    for _ in range(100):
        if high - low <= 1e-11 or f_low == f_high:
            break
        middle = (low * f_high - high * f_low) / (f_high - f_low)
        found, f_middle = _y_for(problem, middle, y_max)[::2]
        if not (found and math.isfinite(f_middle)):
            return False, 0.0
        low, high, f_low, f_high, side, root = _illinois(
            low, high, f_low, f_high, side, middle, f_middle)
        if root:
            return True, middle
    return True, low if abs(f_low) <= abs(f_high) else high


@kernel
def _illinois(low, high, f_low, f_high, side, middle, f_middle):
    """
    Narrow the bracket [low, high] to the trial ``middle`` (the Illinois method).

    Returns (low, high, f_low, f_high, side, root): the function's values
    at the new ends (the end kept twice in a row halved), which end moved
    last (-1 high, 1 low), and whether ``middle`` is a root (f_middle is 0).
    """
    if f_middle * f_high > 0.0:
        if side == -1:
            f_low *= 0.5
        return low, middle, f_low, f_middle, -1, False
    if f_middle * f_low > 0.0:
        if side == 1:
            f_high *= 0.5
        return middle, high, f_middle, f_high, 1, False
    return low, high, f_low, f_high, side, True
