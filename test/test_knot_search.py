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

"""The knot search's early stops: the knots of evaluating every check point of every segment."""

import dataclasses

from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core import knots as knot_search
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.joint_trajectory import MotionSamples
from ellipath_ros.core.kinematics import _kernel_geometry
from ellipath_ros.core.knots import minimal_knots
from ellipath_ros.core.planner import plan_transfer
from ellipath_ros.core.planner import PlannerConfig
import numpy as np
import pytest

CONFIG = PlannerConfig()
# The kernels of the search that decide where an evaluation may stop early.
SEARCH_KERNELS = ('_search_knots', '_segment_errors', '_refine', '_prune', '_replace')


def bench_legs(config, count):
    """Return the motions of the transfer legs of the bench's first ``count`` pairs."""
    motions = []
    for pick, place in random_pairs(count):
        try:
            motions.append(plan_transfer(pick, place, config).motion)
        except EllipathError:
            continue
    return motions


LEGS = {'g2': bench_legs(CONFIG, 24),
        'curvature': bench_legs(dataclasses.replace(CONFIG, profile='curvature', join='paper'),
                                12)}


def evaluate_whole(monkeypatch):
    """Make the search evaluate every check point of every segment (it stops nowhere early)."""
    for name in SEARCH_KERNELS:
        monkeypatch.setattr(knot_search, name, getattr(knot_search, name).py_func)
    evaluated = knot_search._evaluated_errors

    def whole(knots, start, end, table, planned, geometry, fractions, limit, all_or_none=False):
        return evaluated(knots, start, end, table, planned, geometry, fractions, np.inf, False)

    monkeypatch.setattr(knot_search, '_evaluated_errors', whole)


def knots_of(motion, tolerance, samples):
    """Return the knots' arrays and the reported error of :func:`minimal_knots`."""
    traj, error = minimal_knots(motion, CONFIG.geometry, tolerance=tolerance, samples=samples)
    return (traj.time_from_start, traj.positions, traj.velocities, traj.accelerations), error


@pytest.mark.parametrize('kind', sorted(LEGS))
def test_early_stops_keep_the_knots_of_whole_evaluations(kind, monkeypatch):
    # The bench's legs, at the default tolerance, a tenth of it and (below the planned
    # table's resolution, where the search stops for the motion's positions and runs again)
    # a twentieth; and on a sparse sample set, where it stops for states too.
    cases = []
    for motion in LEGS[kind]:
        samples = MotionSamples.of(motion, CONFIG.geometry)
        cases += [(motion, tolerance, samples) for tolerance in (1e-4, 1e-5, 5e-6)]
    motion = LEGS[kind][0]
    grid = np.linspace(0.0, motion.duration, 9)
    cases.append((motion, 5e-6, MotionSamples(motion, CONFIG.geometry, grid,
                                              motion.state_at(grid))))
    found = [knots_of(*case) for case in cases]
    evaluate_whole(monkeypatch)
    for case, (knots, error) in zip(cases, found):
        whole_knots, whole_error = knots_of(*case)
        assert all(np.array_equal(mine, theirs) for mine, theirs in zip(knots, whole_knots))
        assert error == whole_error


def test_too_fine_names_the_whole_error_of_the_segment_left(monkeypatch):
    motion = LEGS['g2'][0]
    samples = MotionSamples.of(motion, CONFIG.geometry)
    messages = []
    for prepare in (lambda: None, lambda: evaluate_whole(monkeypatch)):
        prepare()
        with pytest.raises(InvalidInputError, match='tolerance the motion can meet') as raised:
            minimal_knots(motion, CONFIG.geometry, tolerance=1e-7, min_interval=2e-3,
                          samples=samples)
        messages.append(str(raised.value))
    assert messages[0] == messages[1]


def test_evaluated_errors_stop_above_the_limit():
    # Segments of every length from 5 to 120 ms along a leg: the short ones pass, the long
    # ones fail.
    motion = LEGS['g2'][3]
    samples = MotionSamples.of(motion, CONFIG.geometry)
    ends = np.linspace(0.0, motion.duration, 60)
    starts = np.maximum(ends - np.linspace(0.005, 0.12, 60), 0.0)
    times = np.sort(np.concatenate((starts, ends)))
    states = samples.states(times)
    knots = tuple(np.ascontiguousarray(values) for values in (times, *states[1:]))
    start = np.searchsorted(times, starts)
    end = np.searchsorted(times, ends)
    keep = end > start
    start, end = start[keep], end[keep]
    table = knot_search._planned_table(samples, 1e-4)
    geometry = _kernel_geometry(CONFIG.geometry)[:5]
    fractions = np.arange(1, 25) / 25.0
    planned = (np.empty(0), np.empty((0, 3)))

    def errors(limit, all_or_none):
        status, values, _ = knot_search._evaluated_errors(
            knots, start, end, table, planned, geometry, fractions, limit, all_or_none)
        assert status == knot_search._FOUND
        return values

    whole = errors(np.inf, False)
    limit = 0.95e-4
    passed = whole <= limit
    assert passed.any() and not passed.all()
    stopped = errors(limit, False)
    assert np.array_equal(stopped[passed], whole[passed])
    assert (stopped[~passed] > limit).all() and (stopped[~passed] <= whole[~passed]).all()
    # All or none: up to the first failing segment the same, from it on inf.
    first = np.flatnonzero(~passed)[0]
    batch = errors(limit, True)
    assert np.array_equal(batch[:first], whole[:first])
    assert np.isinf(batch[first:]).all()


def test_a_search_going_on_from_its_stops_finds_what_one_run_finds(monkeypatch):
    # A run after a stop for states starts at the round or trial that stopped (a checkpoint),
    # not at the initial knots. Given every state and planned position the runs asked for
    # before it starts, one run from the initial knots stops nowhere and must find the same
    # knots and error. Curvature legs stop in both steps; a sparse sample set below the
    # planned table's resolution stops for positions too (the checkpoint kept, the journal
    # replayed).
    search = knot_search._search_knots
    runs = []

    def recorded(*arguments):
        result = search(*arguments)
        runs.append((arguments, result))
        return result

    monkeypatch.setattr(knot_search, '_search_knots', recorded)
    motion = LEGS['curvature'][0]
    grid = np.linspace(0.0, motion.duration, 9)
    cases = [(motion, 1e-4, MotionSamples.of(motion, CONFIG.geometry))
             for motion in LEGS['curvature']]
    cases.append((motion, 5e-6, MotionSamples(motion, CONFIG.geometry, grid,
                                              motion.state_at(grid))))
    phases, stops = set(), set()
    for case in cases:
        runs.clear()
        knots, error = knots_of(*case)
        phases.update(arguments[-1][0] for arguments, _ in runs)
        stops.update(result[0] for _, result in runs[:-1])
        arguments, _ = runs[-1]
        once = search(*arguments[:-2], np.empty(0), knot_search._START)
        assert once[0] == knot_search._FOUND
        assert all(np.array_equal(mine, theirs) for mine, theirs in zip(knots, once[1:5]))
        assert error == once[5]
    assert {knot_search._REFINING, knot_search._REPLACING} <= phases
    assert stops == {knot_search._NEEDS_STATES, knot_search._NEEDS_PLANNED}
