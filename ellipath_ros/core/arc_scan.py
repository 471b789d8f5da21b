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
        self.left = steps

    def spend(self):
        """Count one step; raise _NoMotion once the budget is spent."""
        self.left -= 1
        if self.left < 0:
            raise _NoMotion()


class _ArcTable:
    """Curvature kappa and dkappa/ds on a uniform grid along the arc, the speed cap per cell."""

    __slots__ = ('length', 'step', 'last', 'kappa', 'kappa_s', 'cap', 'at', 'cap_at')

    def __init__(self, length, kappa, kappa_s, cap):
        # Lists, not arrays: the scans read single values, which lists serve faster.
        self.length = length
        self.step = length / (len(kappa) - 1)
        self.last = len(kappa) - 2
        self.kappa, self.kappa_s, self.cap = kappa, kappa_s, cap
        self.at = _lookup(self.step, self.last, kappa, kappa_s, cap)
        self.cap_at = _cap_lookup(self.step, self.last, cap)

    def backwards(self):
        """Return the table of the arc run from T2 to T1 (dkappa/ds changes sign)."""
        return _ArcTable(self.length, self.kappa[::-1], [-value for value in self.kappa_s[::-1]],
                         self.cap[::-1])


def _lookup(step, last, kappa, kappa_s, cap):
    """Return at(s) -> (kappa, dkappa/ds, speed cap) at arc length s, read from the lists."""
    # A closure over plain lists: the scans call it several times per step, and local names
    # are the cheapest reads Python has.
    def at(s):
        x = s / step
        index = int(x)
        if index < 0:
            index = 0
        elif index > last:
            index = last
        fraction = x - index
        low, low_s = kappa[index], kappa_s[index]
        return (low + fraction * (kappa[index + 1] - low),
                low_s + fraction * (kappa_s[index + 1] - low_s), cap[index])
    return at


def _cap_lookup(step, last, cap):
    """Return cap_at(s) -> the speed cap of the cell at arc length s (what ``at`` reads)."""
    def cap_at(s):
        index = int(s / step)
        if index < 0:
            index = 0
        elif index > last:
            index = last
        return cap[index]
    return cap_at


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

    def __init__(self, table, limits, budget):
        self.table = table
        self.budget = budget
        self.speed = limits.max_speed * _SPEED_MARGIN
        self.accel = limits.max_accel * _ACCEL_MARGIN
        self.jerk = limits.max_jerk * _JERK_MARGIN
        self.factor = [1.0] * (len(table.kappa) + 1)
        # The scan's inner loop reads these thousands of times per leg: plain attributes.
        self._at = table.at
        self._cap_at = table.cap_at
        self._accel_squared = self.accel ** 2
        self._jerk_squared = self.jerk ** 2
        self._cell = table.step
        self._last_factor = len(self.factor) - 1

    def jerk_range(self, s, v, a):
        """Return the (lowest, highest) s''' keeping |jerk| <= limit at (s, v, a), or None."""
        kappa, kappa_s, _ = self._at(s)
        return self._jerk_range(kappa, kappa_s, v, a)

    def _jerk_range(self, kappa, kappa_s, v, a):
        # |jerk|**2 = (s''' - kappa**2 v**3)**2 + (kappa_s v**3 + 3 kappa v a)**2.
        v3 = v * v * v
        normal = kappa_s * v3 + 3.0 * kappa * v * a
        if abs(normal) >= self.jerk:
            return None
        room = math.sqrt(self._jerk_squared - normal * normal)
        return kappa * kappa * v3 - room, kappa * kappa * v3 + room

    def _legal(self, s, v, a, h, jerk):
        """Return whether ``jerk`` held for ``h`` from (s, v, a) is legal at the step's end."""
        kappa, kappa_s, _ = self._at(s + h * (v + h * (a / 2.0 + h * jerk / 6.0)))
        v, a = v + h * (a + h * jerk / 2.0), a + h * jerk
        # _jerk_range at the end state, written out: this runs several times per step.
        v3 = v * v * v
        normal = kappa_s * v3 + 3.0 * kappa * v * a
        if abs(normal) >= self.jerk:
            return False
        room = math.sqrt(self._jerk_squared - normal * normal)
        middle = kappa * kappa * v3
        return middle - room - 1e-9 <= jerk <= middle + room + 1e-9

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
        tangential = math.sqrt(self._accel_squared - normal * normal)
        target, lowest = tangential, -tangential
        if kappa * v > 0.0:
            share = _NORMAL_JERK_SHARE * math.sqrt(self._jerk_squared - centripetal ** 2)
            target = min(target, (share - kappa_s * v ** 3) / (3.0 * kappa * v))
            lowest = max(lowest, (-share - kappa_s * v ** 3) / (3.0 * kappa * v))
        factor = self.factor[min(max(int(s / self._cell), 0), self._last_factor)]
        target = factor * target if target > 0.0 else target - (1.0 - factor) * self.accel
        return target if target >= lowest else None

    def step(self, s, v, a):
        """Take one scan step from state (s, v, a): (h, s, v, a, jerk) or a failure string."""
        at = self._at
        kappa, kappa_s, cap = at(s)
        # _jerk_range, written out: this is the scan's inner loop.
        v3 = v * v * v
        normal = kappa_s * v3 + 3.0 * kappa * v * a
        speed = min(self.speed, cap)
        if (abs(normal) >= self.jerk or v > speed * (1.0 + 1e-9)
                or (a < 0.0 and v < _MIN_SCAN_SPEED)):
            return 'speed'
        room = math.sqrt(self._jerk_squared - normal * normal)
        lowest, highest = kappa * kappa * v3 - room, kappa * kappa * v3 + room
        h = _SCAN_STEP if kappa <= _SCAN_KAPPA else _SCAN_STEP_SHORT
        if v * abs(kappa_s) * h > _SCAN_KAPPA_CHANGE * kappa:
            # The curvature changes fast here (a needle-sharp bend): shorter steps.
            h = max(_SCAN_KAPPA_CHANGE * kappa / (v * abs(kappa_s)), _SCAN_STEP_MIN)
        # Levelling off ramps s'' down with a share of the jerk the state leaves for it.
        level = _LEVEL_OFF_JERK * max(-lowest, 1e-3 * self.jerk)
        # Level off (and cruise) at the lowest speed limit until where the levelling off
        # would end.
        reach = v * max(a, _LEVEL_REACH * self.accel) / level
        cap_at = self._cap_at
        goal = min(speed, cap_at(s + 0.5 * reach), cap_at(s + reach))
        if a <= 1e-12 and v >= goal * (1.0 - 1e-9):
            jerk, a = 0.0, 0.0
            # Cruising changes nothing but the place: up to half a table cell per step.
            h = max(h, 0.5 * self._cell / v)
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
                    jerk, h = self._level_off(v, a, goal, _SCAN_STEP_SHORT, level)
            elif a > 0.0 > a1 and v - a * a / (2.0 * jerk) > goal:
                # s'' passes 0 inside the step: its speed peak must stay below the limit too.
                jerk, h = self._level_off(v, a, goal, h, level)
        if jerk >= lowest - 1e-9:
            if not self._legal(s, v, a, h, jerk):
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
        """Return the largest jerk in [lowest, ``jerk``] legal at the step's end, or None."""
        legal = self._legal
        low, high, best = lowest, jerk, None
        for _ in range(12):
            middle = 0.5 * (low + high)
            if legal(s, v, a, h, middle):
                best, low = middle, middle
            else:
                high = middle
        return best

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
        self.budget.spend()
        result = self.step(scan.s[-1], scan.v[-1], scan.a[-1])
        if not isinstance(result, str):
            h, s1, v1, a1, jerk = result
            scan.t.append(scan.t[-1] + h)
            scan.s.append(s1)
            scan.v.append(v1)
            scan.a.append(a1)
            scan.j.append(jerk)
            return True
        if result == 'speed' or scan.failures >= _BACK_UP_LIMIT or not back_up:
            scan.status = result
            return False
        scan.failures += 1
        last = len(scan.s) - 1
        first = max(0, last - _BACK_UP_STEPS)
        step = self.table.step
        bins = range(max(int(scan.s[first] / step), 0),
                     min(int((scan.s[last] + _BACK_UP_AHEAD) / step) + 1, len(self.factor)))
        lowered = _BACK_UP_FACTOR * min(self.factor[index] for index in bins)
        for index in bins:
            self.factor[index] = min(self.factor[index], lowered)
        for values in (scan.t, scan.s, scan.v, scan.a):
            del values[first + 1:]
        del scan.j[first:]
        return True
