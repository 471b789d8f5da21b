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
The path-space scan of the time-optimal profile: one greedy, jerk-limited scan along the arc.

:class:`_Scanner` steps a :class:`_Scan` (states t, s, s', s'' and the jerk of each step)
forwards from T1 or, on the mirrored :class:`_ArcTable`, backwards from T2, taking the largest
jerk legal at both ends of each step; :mod:`~ellipath_ros.core.optimal_profile` runs two of
them, joins them and handles speed valleys, end speeds and the fallback. Every step counts
against the plan's :class:`_StepBudget`.
"""

from bisect import bisect_right
import math

import numpy as np

from .limits import _ACCEL_MARGIN, _JERK_MARGIN, _SPEED_MARGIN

# Time step of the path-space scans [s]: the short one where the curvature (1/m) is above
# _SCAN_KAPPA, where the limits change fast along the path.
_SCAN_STEP = 1e-3
_SCAN_STEP_SHORT = 5e-4
_SCAN_KAPPA = 8.0
# ... and shorter still where the curvature changes by more than this share within a step
# (not below _SCAN_STEP_MIN).
_SCAN_KAPPA_CHANGE = 0.1
_SCAN_STEP_MIN = 2e-5
# Share of the jerk budget the scans give the normal component (3 kappa v a + kappa_s v**3),
# leaving the rest for changing the tangential acceleration.
_NORMAL_JERK_SHARE = 0.9
# Levelling off looks ahead by the distance it takes at least at this share of max_accel.
_LEVEL_REACH = 0.1
# A scan slowing down below this speed [m/s] stops (the other scan covers the rest).
_MIN_SCAN_SPEED = 1e-3
# Share of the jerk available in the state with which a scan ramps its acceleration down when
# it levels off at the speed limit.
_LEVEL_OFF_JERK = 0.9
# A scan that cannot follow a falling acceleration bound backs up this many steps and lowers
# its acceleration target by this factor over the troubled stretch, at most this often.
_BACK_UP_STEPS = 20
_BACK_UP_AHEAD = 5e-3
_BACK_UP_FACTOR = 0.75
_BACK_UP_LIMIT = 30


class _NoMotion(Exception):
    """The scans found no motion for a stretch (the caller tries something slower)."""


class _StepBudget:
    """The scan steps a plan may still take (shared by its two scanners)."""

    __slots__ = ('left',)

    def __init__(self, steps):
        # Spent by _Scanner.advance, which raises _NoMotion once it is below 0.
        self.left = steps


class _ArcTable:
    """Curvature kappa and dkappa/ds on a uniform grid along the arc, the speed cap per cell."""

    __slots__ = ('length', 'step', 'last', 'arrays', 'kappa', 'kappa_s', 'cap', 'kappa_rise',
                 'kappa_s_rise', 'at')

    def __init__(self, length, kappa, kappa_s, cap):
        """Build the table from NumPy arrays of equal length (grid points; cap per cell)."""
        self.length = length
        self.step = length / (len(kappa) - 1)
        self.last = len(kappa) - 2
        self.arrays = kappa, kappa_s, cap
        # Lists, not arrays: the scans read single values, which lists serve faster. Each
        # cell's rise too, so that interpolating reads one value less.
        self.kappa, self.kappa_s, self.cap = kappa.tolist(), kappa_s.tolist(), cap.tolist()
        self.kappa_rise, self.kappa_s_rise = np.diff(kappa).tolist(), np.diff(kappa_s).tolist()
        self.at = _lookup(self)

    def backwards(self):
        """Return the table of the arc run from T2 to T1 (dkappa/ds changes sign)."""
        kappa, kappa_s, cap = self.arrays
        return _ArcTable(self.length, kappa[::-1], -kappa_s[::-1], cap[::-1])


def _lookup(table):
    """Return at(s) -> (kappa, dkappa/ds, speed cap) at arc length s, read from ``table``."""
    step, last, cap = table.step, table.last, table.cap
    kappa, kappa_rise, kappa_s, kappa_s_rise = (
        table.kappa, table.kappa_rise, table.kappa_s, table.kappa_s_rise)

    # A closure over plain lists, local names being the cheapest reads Python has: the scan
    # steps read the table through it where they do not interpolate inline.
    def at(s):
        x = s / step
        index = int(x)
        if index < 0:
            index = 0
        elif index > last:
            index = last
        fraction = x - index
        return (kappa[index] + fraction * kappa_rise[index],
                kappa_s[index] + fraction * kappa_s_rise[index], cap[index])
    return at


class _Scan:
    """
    States (t, s, s', s'') of a greedy scan along the arc and the jerk of each step.

    ``t``, ``s``, ``v``, ``a`` have one entry per state, ``j`` one per step.
    ``status`` is 'live', 'end' (reached ``end``), 'speed' (the speed became
    too high for what lies ahead: the other scan covers it) or 'accel' (gave
    up after ``failures`` back-ups).
    """

    __slots__ = ('t', 's', 'v', 'a', 'j', 'end', 'status', 'failures', 'reading')

    def __init__(self, s, v, a, end):
        self.t, self.s, self.v, self.a, self.j = [0.0], [s], [v], [a], []
        self.end, self.status, self.failures = end, 'live', 0
        # The table read at the last state by the step that reached it (see _Scanner.step).
        self.reading = None

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
        t, s, v, a, j = self.t, self.s, self.v, self.a, self.j
        if not j:
            return t[0]
        last = len(j) - 1
        index = min(max(bisect_right(s, s_query) - 1, 0), last)
        low, high = t[index], t[min(index + 1, len(t) - 1)]
        # Bisection on the position, each piece evaluated as :meth:`state` does (same piece,
        # same arithmetic); it stops once the middle no longer moves.
        middle = 0.5 * (low + high)
        for _ in range(60):
            piece = min(max(bisect_right(t, middle) - 1, 0), last)
            x = middle - t[piece]
            if s[piece] + x * (v[piece] + x * (a[piece] / 2.0 + x * j[piece] / 6.0)) < s_query:
                low = middle
            else:
                high = middle
            previous, middle = middle, 0.5 * (low + high)
            if middle == previous:
                break
        return middle

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

    def __init__(self, table, limits, budget):
        self.table = table
        self.budget = budget
        self.speed = limits.max_speed * _SPEED_MARGIN
        self.accel = limits.max_accel * _ACCEL_MARGIN
        self.jerk = limits.max_jerk * _JERK_MARGIN
        # Per table cell, the share of the acceleration target left by back-ups; None until
        # the first (every share 1, which changes no target).
        self.factor = None
        self._jerk_squared = self.jerk ** 2
        self._accel_squared = self.accel ** 2
        # What every step reads, in one tuple (one attribute read instead of a dozen).
        self._constants = (
            table.step, table.last, table.cap, table.kappa, table.kappa_rise, table.kappa_s,
            table.kappa_s_rise, self.speed, self.jerk, self.accel, self._jerk_squared,
            self._accel_squared)

    def jerk_range(self, s, v, a):
        """Return the (lowest, highest) s''' keeping |jerk| <= limit at (s, v, a), or None."""
        kappa, kappa_s, _ = self.table.at(s)
        # |jerk|**2 = (s''' - kappa**2 v**3)**2 + (kappa_s v**3 + 3 kappa v a)**2.
        v3 = v * v * v
        normal = kappa_s * v3 + 3.0 * kappa * v * a
        if abs(normal) >= self.jerk:
            return None
        room = math.sqrt(self._jerk_squared - normal * normal)
        return kappa * kappa * v3 - room, kappa * kappa * v3 + room

    def step(self, scan):
        """
        Take one step of ``scan`` from its last state: None, or why it cannot ('speed', 'accel').

        The step takes the largest jerk within the jerk norm at the state whose
        end state stays below the acceleration target there (see the comment in
        the loop), levels off before the speed limit ahead, and is legal at its
        end (else the largest legal jerk, bisected towards the lowest). The new
        state is appended to ``scan`` with the table's reading there, which the
        next step starts from.
        """
        # The scan's inner loop (hundreds of steps per leg): the table is interpolated inline
        # and every attribute read once, since a Python call, tuple or attribute read costs as
        # much as the arithmetic itself.
        sqrt = math.sqrt
        (cell, last, caps, kappas, kappa_rises, kappa_ss, kappa_s_rises, speed, jerk_limit,
         accel_limit, jerk_squared, accel_squared) = self._constants
        reading = scan.reading
        if reading is None:
            s, v, a = scan.s[-1], scan.v[-1], scan.a[-1]
            kappa, kappa_s, cap = self.table.at(s)
            # The jerk range at (s, v, a): |jerk|**2 = (s''' - kappa**2 v**3)**2
            # + (kappa_s v**3 + 3 kappa v a)**2, the middle of the range kappa**2 v**3.
            v3 = v * v * v
            normal = kappa_s * v3 + 3.0 * kappa * v * a
            if normal >= jerk_limit or -normal >= jerk_limit:
                return 'speed'
            middle, room = kappa * kappa * v3, sqrt(jerk_squared - normal * normal)
        else:
            # The previous step read the table at this state (and found its jerk range).
            s, v, a, kappa, kappa_s, cap, middle, room = reading
        if cap < speed:
            speed = cap
        if v > speed * (1.0 + 1e-9) or (a < 0.0 and v < _MIN_SCAN_SPEED):
            return 'speed'
        lowest, highest = middle - room, middle + room
        h = _SCAN_STEP if kappa <= _SCAN_KAPPA else _SCAN_STEP_SHORT
        if v * abs(kappa_s) * h > _SCAN_KAPPA_CHANGE * kappa:
            # The curvature changes fast here (a needle-sharp bend): shorter steps.
            h = max(_SCAN_KAPPA_CHANGE * kappa / (v * abs(kappa_s)), _SCAN_STEP_MIN)
        # Levelling off ramps s'' down with a share of the jerk the state leaves for it.
        level = 1e-3 * jerk_limit
        if -lowest >= level:
            level = -lowest
        level *= _LEVEL_OFF_JERK
        # Level off (and cruise) at the lowest speed limit until where the levelling off
        # would end.
        reach = _LEVEL_REACH * accel_limit
        if a >= reach:
            reach = a
        reach = v * reach / level
        goal = speed
        for ahead in (s + 0.5 * reach, s + reach):
            index = int(ahead / cell)
            if index < 0:
                index = 0
            elif index > last:
                index = last
            if caps[index] < goal:
                goal = caps[index]
        # Whether the table's reading at the step's end (s_end, v_end, kappa_end, kappa_s_end,
        # cap_end) is that of the jerk and step chosen.
        read = False
        if a <= 1e-12 and v >= goal * (1.0 - 1e-9):
            jerk, a = 0.0, 0.0
            # Cruising changes nothing but the place: up to half a table cell per step.
            h = max(h, 0.5 * cell / v)
        elif a > 0.0 and v + a * a / (2.0 * level) >= goal * (1.0 - 1e-12):
            jerk, h = self._level_off(v, a, goal, h, level)
        else:
            factors = self.factor
            # The factors' last index (they cover the table's points and one beyond).
            last_factor = len(kappas)
            normal_share = _NORMAL_JERK_SHARE
            half_a = a / 2.0
            jerk = highest
            for _ in range(12):
                h_jerk = h * jerk
                s_end = s + h * (v + h * (half_a + h_jerk / 6.0))
                v_end = v + h * (a + h_jerk / 2.0)
                x = s_end / cell
                cell_index = int(x)
                index = cell_index
                if index < 0:
                    index = 0
                elif index > last:
                    index = last
                fraction = x - index
                kappa_end = kappas[index] + fraction * kappa_rises[index]
                kappa_s_end = kappa_ss[index] + fraction * kappa_s_rises[index]
                cap_end = caps[index]
                # The largest s'' to aim at in the end state (None if v is too high there).
                # Below the acceleration norm, and such that the normal jerk
                # 3 kappa v s'' + kappa_s v**3 leaves a share of the jerk budget for changing
                # s'' (with s''' = 0 feasible: the tangential part of p''' v**3 is
                # -kappa**2 v**3). Negative where the curvature tightens too fast for the
                # speed: the scan then slows down. A back-up lowers it.
                target = None
                kappa_v = kappa_end * v_end
                normal_accel = kappa_v * v_end
                v_cubed = v_end ** 3
                centripetal = kappa_end * kappa_end * v_cubed
                if (v_end > 0.0 and v_end <= cap_end * (1.0 + 1e-9)
                        and normal_accel < accel_limit and centripetal < jerk_limit):
                    target = sqrt(accel_squared - normal_accel * normal_accel)
                    floor = -target
                    if kappa_v > 0.0:
                        share = normal_share * sqrt(jerk_squared - centripetal ** 2)
                        change = kappa_s_end * v_cubed
                        divisor = 3.0 * kappa_end * v_end
                        bound = (share - change) / divisor
                        if bound < target:
                            target = bound
                        bound = (-share - change) / divisor
                        if bound > floor:
                            floor = bound
                    if factors is not None:
                        factor = factors[0 if cell_index < 0 else last_factor
                                         if cell_index > last_factor else cell_index]
                        target = (factor * target if target > 0.0
                                  else target - (1.0 - factor) * accel_limit)
                    if not target >= floor:
                        target = None
                if target is None:
                    # Too fast at the step's end: try less jerk (down to the lowest).
                    if jerk <= lowest + 1e-9:
                        return 'speed'
                    jerk = 0.5 * (jerk + lowest)
                    continue
                if a + h_jerk <= target + 1e-12:
                    read = True
                    break
                jerk = (target - a) / h
            a1, v1 = a + jerk * h, v + h * (a + h * jerk / 2.0)
            if a1 > 0.0 and v1 + a1 * a1 / (2.0 * level) > goal:
                read = False
                h = self._until_level_off(v, a, jerk, h, goal, level)
                if h <= 1e-12:
                    jerk, h = self._level_off(v, a, goal, _SCAN_STEP_SHORT, level)
            elif a > 0.0 > a1 and v - a * a / (2.0 * jerk) > goal:
                # s'' passes 0 inside the step: its speed peak must stay below the limit too.
                read = False
                jerk, h = self._level_off(v, a, goal, h, level)
        if not jerk >= lowest - 1e-9:
            # Not accelerating, the speed itself is too high for what follows.
            return 'accel' if a > 1e-9 else 'speed'
        # The jerk must be legal at the step's end too; if it is not, the largest legal one
        # in [lowest, jerk] is bisected for (12 halvings).
        low, high, legal, trial = lowest, jerk, None, jerk
        for halving in range(13):
            if not read:
                s_end = s + h * (v + h * (a / 2.0 + h * trial / 6.0))
                v_end = v + h * (a + h * trial / 2.0)
                kappa_end, kappa_s_end, cap_end = self.table.at(s_end)
            read = False
            a_end = a + h * trial
            v3 = v_end * v_end * v_end
            normal = kappa_s_end * v3 + 3.0 * kappa_end * v_end * a_end
            if normal < jerk_limit and -normal < jerk_limit:
                room = sqrt(jerk_squared - normal * normal)
                middle = kappa_end * kappa_end * v3
                if middle - room - 1e-9 <= trial <= middle + room + 1e-9:
                    legal_jerk = trial
                    legal = s_end, v_end, a_end, kappa_end, kappa_s_end, cap_end, middle, room
                    if halving == 0:
                        break
                    low = trial
                    trial = 0.5 * (low + high)
                    continue
            high = trial
            trial = 0.5 * (low + high)
        if legal is None:
            return 'accel' if a > 1e-9 else 'speed'
        scan.reading = legal
        scan.t.append(scan.t[-1] + h)
        scan.s.append(legal[0])
        scan.v.append(legal[1])
        scan.a.append(legal[2])
        scan.j.append(legal_jerk)
        return None

    def _level_off(self, v, a, speed, h, level):
        """Return (jerk, step): constant jerk bringing s'' to 0 exactly at s' = speed."""
        gap = speed - v
        jerk = -level if gap <= 0.0 else max(-a * a / (2.0 * gap), -self.jerk)
        return jerk, min(h, a / -jerk)

    def _until_level_off(self, v, a, jerk, h, speed, level):
        """Return the time within the step at which v + a**2/(2 level) reaches ``speed``."""
        low, high, twice_level = 0.0, h, 2.0 * level
        for _ in range(40):
            x = 0.5 * (low + high)
            jerk_x = jerk * x
            a1 = a + jerk_x
            if v + x * (a + jerk_x / 2.0) + a1 * a1 / twice_level > speed:
                high = x
            else:
                low = x
        return low

    def advance(self, scan, back_up=True):
        """
        Take one step of ``scan``; return False once it cannot go on (see its status).

        Where the acceleration bound falls faster than the jerk can follow,
        the scan backs up ``_BACK_UP_STEPS`` and lowers its acceleration target
        over the stretch (lower again on repeated trouble).
        """
        if scan.status != 'live':
            return False
        if scan.s[-1] >= scan.end:
            scan.status = 'end'
            return False
        budget = self.budget
        budget.left -= 1
        if budget.left < 0:
            raise _NoMotion()
        failure = self.step(scan)
        if failure is None:
            return True
        if failure == 'speed' or scan.failures >= _BACK_UP_LIMIT or not back_up:
            scan.status = failure
            return False
        scan.failures += 1
        last = len(scan.s) - 1
        first = max(0, last - _BACK_UP_STEPS)
        step = self.table.step
        if self.factor is None:
            self.factor = [1.0] * (len(self.table.kappa) + 1)
        low = max(int(scan.s[first] / step), 0)
        high = min(int((scan.s[last] + _BACK_UP_AHEAD) / step) + 1, len(self.factor))
        # A share of the stretch's lowest is below every share in it: all become that.
        self.factor[low:high] = [_BACK_UP_FACTOR * min(self.factor[low:high])] * (high - low)
        for values in (scan.t, scan.s, scan.v, scan.a):
            del values[first + 1:]
        del scan.j[first:]
        scan.reading = None
        return True
