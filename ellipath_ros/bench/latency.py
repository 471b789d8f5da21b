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
Planning latency in this process, on seeded random reachable pick/place pairs.

The pairs are drawn with NumPy's ``default_rng(seed)``: pick and place uniform over the
default workspace (a disc of radius ``WORKSPACE_RADIUS`` around the axis, z uniform in
``WORKSPACE_Z``), redrawn when they lie less than ``MIN_HORIZONTAL_OFFSET`` apart
horizontally. Requests are chained as the node chains them when no joint state comes in:
the first starts at the node's ``home_position``, each later one where the last planned
one ended (its place). A pair the planner rejects is counted by its error kind and
skipped; the chain goes on from the last planned place.

Each section stops at its pair count or when its wall-time budget is spent, whichever comes
first, and says which (``n`` is what was measured). Every figure is a wall time on the
steady clock (``time.perf_counter``) of this process, with the machine as loaded as it is.
"""

from dataclasses import dataclass
from dataclasses import replace
import math
import time

from ellipath_ros.conversions import serialized_joint_trajectory
from ellipath_ros.conversions import SerializedTrajectory
from ellipath_ros.core.controller import executed_tcp
from ellipath_ros.core.controller import JazzyJtcEmulator
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import plan_transfer
import numpy as np

DEFAULT_SEED = 2023
WORKSPACE_RADIUS = 0.35  # m
WORKSPACE_Z = (-0.95, -0.6)  # m
MIN_HORIZONTAL_OFFSET = 0.005  # m
# The executed motion: JTC at 1 kHz; it runs a little past the last point to see it settle.
CONTROL_PERIOD = 0.001  # s
SETTLE_TIME = 0.005  # s


@dataclass(frozen=True)
class Request:
    """
    A planned request: where it starts, the pair, its trajectory and its serialized message.

    The trajectory, not the whole plan: a plan holds each leg's sampled motion (about 0.9 MiB,
    230 pages), and keeping every plan made each measured request fault in fresh pages and
    the collector walk the kept ones, which the node, done with a plan once it has run, does
    not pay.
    """

    start: np.ndarray
    pick: np.ndarray
    place: np.ndarray
    trajectory: JointTrajectoryData
    message: SerializedTrajectory


@dataclass
class Section:
    """
    Wall times of one measured section, and why it stopped.

    Attributes
    ----------
    times : list of float
        One wall time per measured item [s].
    requested : int
        Items the section was asked to measure.
    budget_s : float
        Wall-time budget of the section [s].
    rejected : dict
        Rejected items by error kind.

    """

    times: list
    requested: int
    budget_s: float
    rejected: dict

    @property
    def budget_reached(self):
        """Whether the budget stopped the section before its count."""
        return len(self.times) + sum(self.rejected.values()) < self.requested

    def stats(self):
        """Return ``{p50, p99, max, n}`` in milliseconds (None without a sample)."""
        return latency_stats(self.times)


def latency_stats(times):
    """Return ``{p50, p99, max, n}`` [ms] of wall times [s]; percentiles interpolate."""
    if not times:
        return {'p50': None, 'p99': None, 'max': None, 'n': 0}
    milliseconds = 1e3 * np.asarray(times, dtype=float)
    p50, p99 = np.percentile(milliseconds, [50.0, 99.0])
    return {'p50': float(p50), 'p99': float(p99), 'max': float(milliseconds.max()),
            'n': int(milliseconds.size)}


def random_pairs(count, seed=DEFAULT_SEED):
    """
    Return ``count`` seeded random (pick, place) pairs in the default workspace [m].

    Both points are uniform over the disc r <= ``WORKSPACE_RADIUS`` and z in
    ``WORKSPACE_Z``; a pair closer than ``MIN_HORIZONTAL_OFFSET`` horizontally is redrawn.
    """
    rng = np.random.default_rng(seed)

    def point():
        radius = WORKSPACE_RADIUS * np.sqrt(rng.random())
        angle = 2.0 * np.pi * rng.random()
        return np.array([radius * np.cos(angle), radius * np.sin(angle),
                         rng.uniform(*WORKSPACE_Z)])

    pairs = []
    while len(pairs) < count:
        pick, place = point(), point()
        if np.hypot(*(place - pick)[:2]) >= MIN_HORIZONTAL_OFFSET:
            pairs.append((pick, place))
    return pairs


class _Budget:
    """Counts a section's items and tells when its wall-time budget is spent."""

    def __init__(self, label, count, budget_s, progress):
        self.section = Section([], count, budget_s, {})
        self._label = label
        self._deadline = time.perf_counter() + budget_s
        self._progress = progress

    def items(self, items):
        """Yield ``items`` until the budget is spent, reporting progress."""
        total = len(items)
        for index, item in enumerate(items):
            if time.perf_counter() > self._deadline:
                break
            self._progress(self._label, index, total)
            yield item
        self._progress(self._label, len(self.section.times), total, finished=True)

    def reject(self, error):
        """Count a rejected item by its error kind."""
        self.section.rejected[error.kind] = self.section.rejected.get(error.kind, 0) + 1


def _warm_up(function, *args):
    """Call ``function`` once untimed (first-call imports and caches), ignoring rejections."""
    try:
        function(*args)
    except EllipathError:
        pass


def measure_requests(pairs, home, settings, budget_s, progress):
    """
    Time whole requests: ``plan_cycle`` from the start through pick to place, and the message.

    Parameters
    ----------
    pairs : list of (numpy.ndarray, numpy.ndarray)
        Pick and place [m].
    home : array_like
        Start of the first request [m], the node's ``home_position``.
    settings : ellipath_ros.parameters.NodeSettings
        The node's settings (planner config, dwells, frame).
    budget_s : float
        Wall-time budget [s].
    progress : callable
        Progress reporter ``(label, count, total, finished=False)``.

    Returns
    -------
    tuple
        (Section, list of Request in order).

    """
    budget = _Budget('request', len(pairs), budget_s, progress)
    start = np.asarray(home, dtype=float)

    def request(start, pick, place):
        plan = plan_cycle(start, pick, place, settings.planner, pick_dwell=settings.pick_dwell,
                          place_dwell=settings.place_dwell)
        return plan, serialized_joint_trajectory(plan.joint_trajectory, settings.frame_id)

    _warm_up(request, start, *pairs[0])
    requests = []
    for pick, place in budget.items(pairs):
        began = time.perf_counter()
        try:
            plan, message = request(start, pick, place)
        except EllipathError as error:
            budget.reject(error)
            continue
        budget.section.times.append(time.perf_counter() - began)
        requests.append(Request(start, pick, place, plan.joint_trajectory, message))
        start = plan.end_position
    return budget.section, requests


def _time_each(budget, items, function):
    """Time ``function(item)`` for the items the budget allows; count the rejected ones."""
    for item in budget.items(items):
        began = time.perf_counter()
        try:
            function(item)
        except EllipathError as error:
            budget.reject(error)
            continue
        budget.section.times.append(time.perf_counter() - began)
    return budget.section


def measure_legs(requests, config, budget_s, progress):
    """Time ``plan_transfer`` from each planned request's pick to its place."""
    return _time_each(_Budget('leg', len(requests), budget_s, progress), requests,
                      lambda request: plan_transfer(request.pick, request.place, config))


def measure_curvature_requests(requests, settings, budget_s, progress):
    """
    Time the planned requests again, from the same starts, with ``profile='curvature'``.

    The paper's node rule lives on the paper's path, so these requests use ``join='paper'``.
    """
    config = replace(settings.planner, profile='curvature', join='paper')

    def request_again(request):
        plan = plan_cycle(request.start, request.pick, request.place, config,
                          pick_dwell=settings.pick_dwell, place_dwell=settings.place_dwell)
        serialized_joint_trajectory(plan.joint_trajectory, settings.frame_id)

    return _time_each(_Budget('curvature request', len(requests), budget_s, progress),
                      requests, request_again)


def measure_messages(requests, frame_id, progress):
    """
    Time building and serialising each planned request's JointTrajectory message.

    The node's way: :func:`~ellipath_ros.conversions.serialized_joint_trajectory` writes the
    serialized message (the bytes that ``publish()`` sends) straight from the arrays, with
    the trajectory of what it holds, which the node checks before it publishes.
    """
    return _time_each(
        _Budget('message', len(requests), math.inf, progress), requests,
        lambda request: serialized_joint_trajectory(request.trajectory, frame_id))


def message_sizes(requests):
    """
    Return the points and the serialized bytes of each planned request's message.

    ``{'points': {p50, p99, max}, 'bytes': {p50, p99, max}, 'n'}``: what a request publishes
    (both legs and the dwells in one JointTrajectory), percentiles interpolated.
    """
    if not requests:
        return {'points': None, 'bytes': None, 'n': 0}
    points = [len(request.message.trajectory.time_from_start) for request in requests]
    sizes = [len(request.message.data) for request in requests]
    return {name: {'p50': float(np.percentile(values, 50.0)),
                   'p99': float(np.percentile(values, 99.0)), 'max': int(max(values))}
            for name, values in (('points', points), ('bytes', sizes))} | {'n': len(requests)}


def executed_peaks(requests, config, budget_s, progress):
    """
    Worst executed TCP speed, acceleration and jerk over the planned requests.

    Each published message goes on its own through the emulation of Jazzy's
    joint_trajectory_controller (1 kHz, velocity state interface, the robot at rest at the
    first point, stamp zero): what the controller commands is JTC's quintic through the
    published points. Forward kinematics of the commands and their finite differences give
    the peaks (:func:`~ellipath_ros.core.controller.executed_tcp`).

    Returns
    -------
    dict
        ``speed``, ``accel``, ``jerk``: ratios of the worst peak to ``max_speed``,
        ``max_accel``, ``max_jerk``; ``peak_speed`` [m/s], ``peak_accel`` [m/s^2],
        ``peak_jerk`` [m/s^3]; ``n`` (trajectories replayed), ``budget_reached`` and
        ``what``.

    """
    budget = _Budget('executed', len(requests), budget_s, progress)
    peaks = np.zeros(3)
    for request in budget.items(requests):
        began = time.perf_counter()
        published = request.message.trajectory
        controller = JazzyJtcEmulator(published.joint_names, period=CONTROL_PERIOD,
                                      initial_positions=published.positions[0])
        controller.receive(published, 0.0, 0.0)
        controller.run_until(published.time_from_start[-1] + SETTLE_TIME)
        tcp = executed_tcp(controller.samples(), config.geometry)
        peaks = np.fmax(peaks, (tcp.peak_speed, tcp.peak_acceleration, tcp.peak_jerk))
        budget.section.times.append(time.perf_counter() - began)
    limits = config.limits
    ratios = peaks / (limits.max_speed, limits.max_accel, limits.max_jerk)
    return {
        'speed': float(ratios[0]), 'accel': float(ratios[1]), 'jerk': float(ratios[2]),
        'peak_speed': float(peaks[0]), 'peak_accel': float(peaks[1]),
        'peak_jerk': float(peaks[2]), 'n': len(budget.section.times),
        'budget_reached': budget.section.budget_reached,
        'what': 'executed: JTC (Jazzy, emulated at 1 kHz) quintic through the published '
                'points, forward kinematics, finite differences; ratios to the limits',
    }
