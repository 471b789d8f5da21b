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
The path-space scans and their join.

The scan's shortcuts and its compiled kernels give what plain code gives; a kept scan
handed out again takes the steps a new one takes; legs whose join once failed are joined.
"""

import math

from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core import arc_scan, optimal_profile
from ellipath_ros.core.arc_scan import _advance, _ADVANCED, _FAILURES, _KNOWN, _READ, _Scan
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.geometry import plan_path
from ellipath_ros.core.limits import _cap_values, _LIMIT_SAMPLES, CartesianLimits
from ellipath_ros.core.planner import _check_reach_and_speed_cap, PlannerConfig
from ellipath_ros.core.ruckig_lines import _line_speed
import numpy as np
import pytest


def _bench_approach(request, join):
    """
    Return (path, speed cap) of the approach leg of the bench's request ``request``.

    The bench's seeded pairs, its request starting at the previous one's place (the caller
    picks a request whose previous one the bench plans), default settings but ``join``.
    """
    pairs = random_pairs(request + 1)
    config = PlannerConfig.from_flat({'join': join})
    path = plan_path(pairs[request - 1][1], pairs[request][0], config.place_clearance,
                     config.pick_clearance, config.arc, config.join, config.join_tolerance)
    return path, _check_reach_and_speed_cap(path, config)


# Bench legs whose join failed at the scans' crossing (the Ruckig fallback served them, at
# 0.786 s and 0.972 s): the join found from scan states before the crossing, or with the
# other jerk sign.
BENCH_LEGS = ((373, 'g2'), (290, 'paper'))
# A bench leg (request, join) whose arc splits at speed valleys 6 times, its scans backing up
# 4 times: 20 scans start where one started before.
SPLIT_LEG = (29, 'g2')
# Legs (path, speed cap) the equivalence tests plan: the paper's example with each join, a
# bend with a speed valley, a low, wide one under a speed cap, a bench leg of BENCH_LEGS
# and SPLIT_LEG.
PATHS = (
    lambda: (plan_path([0, 0, -0.8], [0.3, 0, -0.75]), None),
    lambda: (plan_path([0, 0, -0.8], [0.3, 0, -0.75], join='paper'), None),
    lambda: (plan_path([0.1, -0.05, -0.9], [-0.15, 0.1, -0.78]), None),
    lambda: (plan_path([-0.2, 0.1, -0.85], [0.2, -0.1, -0.85]),
             lambda s: np.full(np.shape(s), 1.5)),
    lambda: _bench_approach(*BENCH_LEGS[0]),
    lambda: _bench_approach(*SPLIT_LEG),
)


def _bisected_time(scan, s_query):
    """Return the time at s_query by 60 bisections through ``state`` (the plain reference)."""
    index = min(max(int(np.searchsorted(scan.s, s_query, side='right')) - 1, 0),
                len(scan.j) - 1)
    low, high = scan.t[index], scan.t[min(index + 1, len(scan.t) - 1)]
    for _ in range(60):
        middle = 0.5 * (low + high)
        if scan.state(middle)[0] < s_query:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def _constructed_scan(seed):
    """Return a scan of random constant-jerk pieces, states chained exactly as a scan's."""
    rng = np.random.default_rng(seed)
    pieces = 40
    scan = _Scan(0.0, 0.5, 0.0, 1.0, pieces + 1, arc_scan._THREE_FLOATS.pack(0.0, 0.5, 0.0))
    t, s, v, a, j = scan.states[:5]
    for index in range(pieces):
        h, jerk = rng.uniform(2e-5, 1e-3), rng.uniform(-2000.0, 2000.0)
        t[index + 1] = t[index] + h
        s[index + 1] = s[index] + h * (v[index] + h * (a[index] / 2.0 + h * jerk / 6.0))
        v[index + 1] = v[index] + h * (a[index] + h * jerk / 2.0)
        a[index + 1] = a[index] + h * jerk
        j[index] = jerk
    scan.info[arc_scan._COUNT] = pieces + 1
    return scan


def test_time_at_is_the_plain_bisection_to_the_last_bit():
    for seed in range(5):
        scan = _constructed_scan(seed)
        queries = np.concatenate((scan.s, np.linspace(scan.s[0], scan.s[-1], 97)[1:-1]))
        for s_query in queries:
            assert scan.time_at(s_query) == _bisected_time(scan, s_query)


def _forward_scan(path, forget_readings):
    """Return the forward scan of the whole arc from rest speed 0.3 m/s (until it stops)."""
    planner = optimal_profile._ArcPlanner(path, CartesianLimits(), None)
    scan = planner.forward.scan(0.0, 0.3, 0.0, planner.length)
    while True:
        if forget_readings:
            scan.info[_READ] = 0
        if _advance(*planner.forward.parts(), *scan.parts(), True) != _ADVANCED:
            return scan


def test_a_step_starts_from_the_reading_the_table_gives():
    # Each step hands its end state's table reading to the next: the same states result as
    # when every step reads the table afresh.
    for path in (PATHS[0]()[0], PATHS[2]()[0]):
        carried, fresh = _forward_scan(path, False), _forward_scan(path, True)
        assert carried.count > 100
        for name in ('t', 's', 'v', 'a', 'j'):
            assert getattr(carried, name).tobytes() == getattr(fresh, name).tobytes()
        assert carried.status == fresh.status


def _run_scan(scanner, scan):
    """Run ``scan`` until it stops; return (its states as bytes, status, steps spent)."""
    budget = int(scanner.budget[0])
    scanner.run(scan)
    states = b''.join(getattr(scan, name).tobytes() for name in ('t', 's', 'v', 'a', 'j'))
    return states, scan.status, budget - int(scanner.budget[0])


def test_a_kept_scan_takes_the_steps_a_new_scan_takes():
    # A scan from a state a scan started from before is that scan, its steps known: it takes
    # them again as they stand, towards a farther end and a nearer one, and spends the
    # budget as a new scan does (on a scanner of its own).
    path = PATHS[0]()[0]
    kept = optimal_profile._ArcPlanner(path, CartesianLimits(), None).forward
    first = kept.scan(0.0, 0.3, 0.0, 0.4 * kept.cell * (kept.table.shape[1] - 1))
    _run_scan(kept, first)
    assert first.status == 'end' and first.count > 50 and not first.info[_FAILURES]
    for share in (1.0, 0.2):
        end = share * kept.cell * (kept.table.shape[1] - 1)
        again = kept.scan(0.0, 0.3, 0.0, end)
        assert again is first and again.info[_KNOWN] > 50
        new = optimal_profile._ArcPlanner(path, CartesianLimits(), None).forward
        assert _run_scan(kept, again) == _run_scan(new, new.scan(0.0, 0.3, 0.0, end))
    # Another start (-0.0 is not 0.0) is a new scan.
    assert kept.scan(0.0, 0.3, -0.0, 0.1) is not first


def test_a_back_up_forgets_the_steps_that_read_a_lowered_share():
    # A back-up lowers the acceleration shares from an index on: a kept scan is known up to
    # its first step that read a share there, and from there it steps as a new scan steps
    # on the lowered shares.
    path = PATHS[0]()[0]
    scanner = optimal_profile._ArcPlanner(path, CartesianLimits(), None).forward
    end = scanner.cell * (scanner.table.shape[1] - 1)
    first = scanner.scan(0.0, 0.3, 0.0, end)
    before = _run_scan(scanner, first)
    reads = first.states[arc_scan._READS, 1:first.count]
    lowered = int(np.median(reads[reads >= 0.0]))
    stale = 1 + int(np.flatnonzero(reads >= lowered)[0])
    backing = scanner.scan(0.01, 0.3, 0.0, end)
    scanner.factor[lowered:] *= 0.75
    backing.info[arc_scan._LOWERED] = lowered
    again = scanner.scan(0.0, 0.3, 0.0, end)
    assert again is first and again.info[_KNOWN] == stale > 20
    new = optimal_profile._ArcPlanner(path, CartesianLimits(), None).forward
    new.factor[:] = scanner.factor
    after = _run_scan(scanner, again)
    assert after == _run_scan(new, new.scan(0.0, 0.3, 0.0, end))
    assert after[0] != before[0]


@pytest.mark.parametrize('make_path', PATHS)
def test_kept_scans_plan_what_new_scans_plan_bit_for_bit(make_path, monkeypatch):
    # The plan with scans kept and handed out again against the plan with a new scan each
    # time: the same motion to the last bit and the same steps spent (the budget decides
    # when bisections stop and when the scans give up).
    path, cap = make_path()
    limits = CartesianLimits()
    spent = []
    scanner_init = arc_scan._Scanner.__init__

    def recorded(scanner, table, cell, limits, budget):
        scanner_init(scanner, table, cell, limits, budget)
        spent.append((budget, int(budget[0])))

    monkeypatch.setattr(arc_scan._Scanner, '__init__', recorded)
    restarts = []
    restart = arc_scan._Scan.restart

    def counted(scan, end):
        restarts.append(end)
        restart(scan, end)

    monkeypatch.setattr(arc_scan._Scan, 'restart', counted)
    kept = optimal_profile._optimal_motion(path, limits, cap)
    kept_steps = [start - int(budget[0]) for budget, start in spent]
    spent.clear()
    monkeypatch.setattr(arc_scan._Scanner, 'scan', lambda scanner, s, v, a, end: _Scan(
        s, v, a, end, max(int(scanner.budget[0]), 0) + 2, arc_scan._THREE_FLOATS.pack(s, v, a)))
    new = optimal_profile._optimal_motion(path, limits, cap)
    assert _bits(kept) == _bits(new)
    assert kept_steps == [start - int(budget[0]) for budget, start in spent]
    if make_path is PATHS[-1]:
        assert len(restarts) >= 10


def _kernels(module):
    """Return {name: compiled kernel} of ``module``'s own kernels."""
    return {name: value for name, value in vars(module).items()
            if hasattr(value, 'py_func') and value.__module__ == module.__name__}


def _bits(motion):
    """Return the exact bytes of a timed motion's pieces, duration and segments."""
    law = motion.law
    arrays = (law.times, law.s0, law.v0, law.a0, law.jerk, motion.segment_durations)
    return b''.join(np.asarray(array).tobytes() for array in arrays), motion.duration


@pytest.mark.parametrize('make_path', PATHS)
def test_compiled_kernels_plan_what_their_plain_python_plans_bit_for_bit(
        make_path, monkeypatch):
    # The kernels (numba, nopython) against their plain-Python form (py_func): every kernel
    # of the scan's modules swapped for its py_func, so the kernels calling kernels run plain
    # too. Catches an operation numba compiles differently from Python (x**2 as x*x, min/max
    # with NaN, integer division) and any future numba that does.
    path, cap = make_path()
    limits = CartesianLimits()
    compiled = optimal_profile._optimal_motion(path, limits, cap)
    kernels = {**_kernels(arc_scan), **_kernels(optimal_profile)}
    assert {'_advance', '_stop_or_back_up', '_scan_both', '_crossing',
            '_piece_check'} <= set(kernels)
    steps = []
    scanner_init = arc_scan._Scanner.__init__

    def recorded(scanner, table, cell, limits, budget):
        scanner_init(scanner, table, cell, limits, budget)
        steps.append((budget, int(budget[0])))

    for module in (arc_scan, optimal_profile):
        for name in set(kernels) & set(vars(module)):
            monkeypatch.setattr(module, name, kernels[name].py_func)
    monkeypatch.setattr(arc_scan._Scanner, '__init__', recorded)
    plain = optimal_profile._optimal_motion(path, limits, cap)
    # The scans ran (the fallback would not count steps) and ran plain.
    assert sum(start - max(int(budget[0]), 0) for budget, start in steps) > 200
    assert optimal_profile._scan_both is kernels['_scan_both'].py_func
    assert _bits(plain) == _bits(compiled)


def test_piece_check_is_its_plain_form_at_numpys_linspace_points():
    # The piece check (compiled and plain alike) evaluates the 9 points that
    # numpy.linspace(0, duration, 9) gives, computed as NumPy computes them.
    planner = optimal_profile._ArcPlanner(PATHS[0]()[0], CartesianLimits(), None)
    table, constants = planner.forward.table, planner.forward.constants
    for duration in (0.0, 1e-3, 3e-3, 7.1e-3, math.pi * 1e-3):
        for jerk in (-900.0, 400.0):
            legal, worst = optimal_profile._piece_check(
                table, constants, 0.05, 0.6, 1.0, duration, jerk)
            reference = optimal_profile._piece_check.py_func(
                table, constants, 0.05, 0.6, 1.0, duration, jerk)
            assert (legal, worst) == reference
            points = np.linspace(0.0, duration, 9)
            assert points.tolist() == [
                duration if point == 8 else point * (duration / 8) + 0.0 for point in range(9)]


def _least_time(length, limits):
    """
    Return the least time [s] of any rest-to-rest motion over ``length`` [m] within limits.

    Within the speed and acceleration limits alone (s'' is a component of the acceleration
    vector): full acceleration, cruise at the speed limit if there is room, full braking.
    """
    speed, accel = limits.max_speed, limits.max_accel
    if length >= speed * speed / accel:
        return length / speed + speed / accel
    return 2.0 * math.sqrt(length / accel)


@pytest.mark.parametrize('request_index, join', BENCH_LEGS)
def test_a_bench_leg_whose_join_failed_at_the_crossing_is_timed_by_the_scans(
        request_index, join, monkeypatch):
    # Both scans held the speed limit where they crossed, their s'' chattering: the join
    # solved from the crossing found only pieces of negative duration, lower end speeds did
    # not move the crossing, and the Ruckig fallback served at 2.8 (g2) and 5.0 (paper)
    # times the least time of any motion over the path's length within the speed and
    # acceleration limits. The scans' plan takes under 2 (1.47 and 1.60 when written).
    path, cap = _bench_approach(request_index, join)
    limits = PlannerConfig.from_flat({'join': join}).limits
    fallbacks = []
    fallback = optimal_profile._ArcPlanner.fallback

    def recorded(planner, *args):
        fallbacks.append(args)
        return fallback(planner, *args)

    monkeypatch.setattr(optimal_profile._ArcPlanner, 'fallback', recorded)
    motion = optimal_profile._optimal_motion(path, limits, cap)
    assert not fallbacks
    assert motion.duration < 2.0 * _least_time(path.length, limits)


def test_the_planner_asks_the_cap_once_for_its_grid_and_the_end_lines_speeds():
    # One ask of the cap serves the stairs and the lines' speeds at both ends: the speeds
    # are _line_speed's own, bit for bit, and no later ask is made for them.
    path, cap = _bench_approach(*SPLIT_LEG)
    asked = []

    def counted(s):
        asked.append(s.size)
        return cap(s)

    planner = optimal_profile._ArcPlanner(path, CartesianLimits(), counted)
    assert len(asked) == 1 and asked[0] == planner.grid.size + 2 * _LIMIT_SAMPLES
    c1, _, c2 = path.segment_lengths.tolist()
    for start, clearance in ((0.0, c1), (path.length - c2, c2)):
        expected = _line_speed(planner.limits, cap, start, start + clearance)
        assert planner._cap_speed(counted, start, start + clearance) == expected
    assert len(asked) == 1


@pytest.mark.parametrize('failing', ['grid', 'lift', 'descent'])
def test_a_cap_failing_anywhere_is_named_as_its_separate_asks_name_it(failing):
    # The grid's values, then each end line's: the first ask that fails names the failure
    # (its value, s and sample) as if the cap were asked for each on its own.
    path, cap = _bench_approach(*SPLIT_LEG)
    c1, arc, c2 = path.segment_lengths.tolist()
    low, high = {'grid': (c1 + 0.5 * arc, c1 + arc), 'lift': (0.0, 0.5 * c1),
                 'descent': (path.length - 0.5 * c2, path.length + 1.0)}[failing]

    def failing_cap(s):
        return np.where((s > low) & (s < high), 0.0, cap(s))

    planner = optimal_profile._ArcPlanner(path, CartesianLimits(), cap)
    with pytest.raises(InvalidInputError) as separate:
        if failing == 'grid':
            _cap_values(failing_cap, c1 + planner.grid)
        start, clearance = (0.0, c1) if failing == 'lift' else (path.length - c2, c2)
        _line_speed(planner.limits, failing_cap, start, start + clearance)
    with pytest.raises(InvalidInputError) as together:
        optimal_profile._ArcPlanner(path, CartesianLimits(), failing_cap)
    assert str(together.value) == str(separate.value)


def test_the_ceiling_is_computed_where_first_read_the_ends_on_their_own():
    # The end speeds read the ceiling at both ends without the whole grid's being computed;
    # it is the same there, bit for bit, as the grid's (computed for the valleys).
    for make in PATHS:
        path, cap = make()
        planner = optimal_profile._ArcPlanner(path, CartesianLimits(), cap)
        c1, _, c2 = path.segment_lengths.tolist()
        speeds = [planner.end_speed(clearance, at_start, cap)
                  for clearance, at_start in ((c1, True), (c2, False))]
        assert 'ceiling' not in vars(planner)
        ceiling = planner.ceiling
        table = planner.forward.table
        for row in (0, ceiling.size - 1):
            assert optimal_profile._cruise_speed(table, row, *planner._cruise_limits) == (
                ceiling[row])
        assert speeds[0] <= ceiling[0] and speeds[1] <= ceiling[-1]


def test_cap_stairs_are_the_lowest_cap_each_stair_spans():
    # The stairs' kernel against NumPy's form of the same: each cell's lowest end, then each
    # stair's lowest cell, bit for bit.
    rng = np.random.default_rng(3)
    values = rng.uniform(0.2, 3.0, 2049)
    cells = np.full(2048, math.inf)
    optimal_profile._cap_stairs(values, 0.999, 8, cells)
    scaled = 0.999 * values
    lowest = np.minimum(scaled[:-1], scaled[1:]).reshape(-1, 8).min(axis=1)
    assert cells.tobytes() == np.repeat(lowest, 8).tobytes()
    assert cells[8] == 0.999 * values[8:17].min() and np.isfinite(cells).all()


def _valley_index_by_numpy(ceiling, grid_step, forward_end, backward_end, length, s_a, s_b):
    """Return the valley's grid index, or -1, as NumPy found it before the kernel (reference)."""
    margin = 4 * grid_step
    ends = sorted((forward_end, length - backward_end))
    low = int(max(ends[0] - optimal_profile._VALLEY_REACH, s_a + margin) / grid_step)
    high = int(min(ends[1] + optimal_profile._VALLEY_REACH, s_b - margin) / grid_step) + 1
    if high - low < 3:
        return -1
    index = low + int(np.argmin(ceiling[low:high]))
    lowest = ceiling[index]
    if lowest < ceiling[low] * (1.0 - 1e-9) and lowest < ceiling[high - 1] * (1.0 - 1e-9):
        return index
    return -1


def test_the_valley_kernel_finds_numpys_valley():
    # Random ceilings with runs of equal values (argmin's first of equals), every other one
    # sorted (its lowest at an end: no valley), a NaN now and then (argmin's first NaN), scans
    # stopped anywhere in random stretches: the kernel's index against NumPy's form, on both
    # the kernel and its plain form.
    rng = np.random.default_rng(11)
    length, points = 0.4, 2049
    grid_step = length / (points - 1)
    found = 0
    for trial in range(400):
        ceiling = np.round(rng.uniform(0.3, 2.0, points), 1)
        if trial % 2:
            ceiling = np.sort(ceiling)[::-1] if trial % 4 == 1 else np.sort(ceiling)
        if trial % 7 == 0:
            ceiling[rng.integers(points)] = math.nan
        s_a, s_b = np.sort(rng.uniform(0.0, length, 2))
        forward, backward = np.zeros((6, 3)), np.zeros((6, 2))
        forward[1, 2] = rng.uniform(s_a, s_b)
        backward[1, 1] = length - rng.uniform(s_a, s_b)
        expected = _valley_index_by_numpy(ceiling, grid_step, forward[1, 2], backward[1, 1],
                                          length, s_a, s_b)
        for valley_index in (optimal_profile._valley_index,
                             optimal_profile._valley_index.py_func):
            assert valley_index(ceiling, grid_step, forward, 3, backward, 2, length, s_a,
                                s_b) == expected
        found += expected >= 0
    assert 100 < found < 300


def _until_level_off_one_by_one(v, a, jerk, h, speed, level):
    """Return the level-off time by 40 bisections one after another (the plain reference)."""
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


def test_two_bisections_per_pass_find_the_level_off_of_one_by_one_to_the_last_bit():
    # Random steps whose level-off lies inside them, at their ends or beyond them.
    rng = np.random.default_rng(7)
    found = set()
    for _ in range(3000):
        v, a, h = rng.uniform(0.05, 2.0), rng.uniform(0.0, 40.0), rng.uniform(2e-5, 1e-3)
        jerk, level = rng.uniform(-1000.0, 1000.0), rng.uniform(1.0, 900.0)
        speed = v + (a * a / (2.0 * level) + a * h) * rng.uniform(0.5, 1.5)
        expected = _until_level_off_one_by_one(v, a, jerk, h, speed, level)
        assert arc_scan._until_level_off(v, a, jerk, h, speed, level) == expected
        assert arc_scan._until_level_off.py_func(v, a, jerk, h, speed, level) == expected
        found.add(0.0 < expected < h)
    assert found == {True, False}


def test_the_chosen_probes_scan_is_kept_as_a_new_scan_from_its_state_would_step():
    # A G2 end's probes hand their steps to the arc's scans from their end states: the
    # chosen one's scan takes what a new scan takes and spends the budget as a new one does.
    path = plan_path([0.1, -0.05, -0.9], [-0.15, 0.1, -0.78], join='g2')
    clearance = float(path.segment_lengths[0])
    planner = optimal_profile._ArcPlanner(path, CartesianLimits(), None)
    speed, accel = planner.end_state(planner.end_speed(clearance, True, None), clearance,
                                     True, None)
    scan = planner.forward.scan(0.0, speed, accel, planner.length)
    assert scan.info[_KNOWN] > 20 and not scan.info[_FAILURES]
    new = optimal_profile._ArcPlanner(path, CartesianLimits(), None).forward
    assert _run_scan(planner.forward, scan) == _run_scan(
        new, new.scan(0.0, speed, accel, planner.length))
