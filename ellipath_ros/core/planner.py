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
Orchestration: pick and place in, a validated joint trajectory out.

``plan_transfer`` plans one leg (path, timing, kinematics, knots);
``plan_cycle`` chains the approach leg from where the robot is, the dwells
and the transfer leg into one trajectory for the joint_trajectory_controller.
The approach depends on the start and the pick only: ``plan_approach`` plans
it ahead (the node, while it waits for the place) for ``plan_cycle`` to reuse.
Both take a :class:`PlannerConfig`, which the CLI and the node build from the
same flat parameter names (``PlannerConfig.from_flat``).
"""

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, MISSING
import functools
import math
import time

import numpy as np

from .compiled import kernel
from .errors import InvalidInputError, LimitError, require_point
from .geometry import ArcPolicy, PickPlacePath, plan_path, require_coordinates
from .joint_trajectory import (
    _fill_quintic, _polynomial, _SAFETY, check_joint_limits, EXECUTED_KEYS, executed_table,
    JointTrajectoryData, MotionSamples, on_whole_nanoseconds, quintic_interpolate,
    quintic_positions, sample_joint_trajectory, validate_jtc)
from .kinematics import (
    _ASSEMBLED, _forward_point, _ik, _kernel_geometry, DeltaGeometry, forward_kinematics,
    inverse_kinematics, joint_speed_caps, joint_velocities, JointLimits,
    largest_magnitude_per_row)
from .knots import _split_segments, minimal_knots
from .limits import CartesianLimits
from .motion import TimedMotion
from .settings import CORE_NAMES, default_of, SETTING_BY_NAME, validate, validate_fields
from .timing import time_motion
from .workspace import clearance, inside, SafeWorkspace

# Path samples for the reachability check and the joint-speed cap: at most this far apart.
_REACH_CHECK_SPACING = 0.002
# The joint-speed cap is interpolated between path samples: keep a margin for that.
_JOINT_CAP_MARGIN = 0.97
# Interior points per knot segment at which JTC's quintic is checked against the position
# limits where it could reach them (its speed and acceleration extremes are in the executed
# table).
_QUINTIC_CHECK_SAMPLES = 16
# Share of the joint limits the motion itself may use (JTC's quintic may overshoot it).
_JOINT_LIMIT_SHARE = 0.99
# Extra slow-down steps when the interpolated trajectory still breaks a joint limit.
_SLOWDOWN_ATTEMPTS = 4
_SLOWDOWN_STEP = 1.02
# What JTC executes keeps the TCP speed and acceleration limits and the jerk within this
# multiple of its limit (a quintic through points cannot follow the jerk exactly); the checks
# aim _EXECUTED_AIM below each, for what a check finer than theirs could still find.
_EXECUTED_JERK_SHARE = 1.10
_EXECUTED_AIM = 0.999
# Jerk steps of at least this share of max_jerk get a point when their segment breaks a limit
# (not closer than _KNOT_MIN_GAP [s] to another point), for at most _KNOT_ROUNDS rounds.
_JERK_STEP_SHARE = 0.1
_KNOT_MIN_GAP = 1e-5
_KNOT_ROUNDS = 8
# A segment that added points made and that fails the knot search's own check is halved, up
# to this many times: a point changes the quintics on both sides of it, closer to the motion as
# a rule, not always (bench seed 11, pair 831: a point at a jerk step near the end of a 44 ms
# segment left a 40 ms one deviating 120 um where the knots' did 75 um, tolerance 100 um).
_MEND_HALVINGS = 4
# Below this share above the planned motion's peak, an executed peak is the motion's own.
_QUINTIC_EXCESS = 1e-4
# A leg slowed down for the executed limits is slowed this much beyond the measured excess.
_SLOWDOWN_MARGIN = 2e-3
# A leg slower than this is refused before it is sampled (limits far too low, or the paper's
# profile on a needle-thin arc): no pick-and-place cycle takes a minute.
_MAX_LEG_DURATION = 60.0
# Start and pick closer than this: the robot is already at the pick, no approach leg.
_SAME_POINT = 1e-6
# Time step at which the executed motion (JTC's quintic through the points, through forward
# kinematics) is checked against the safe workspace: at 4 m/s the TCP moves 0.4 mm per step,
# so between two samples a bound is crossed by at most max_speed * step / 2 more.
_WORKSPACE_CHECK_PERIOD = 1e-4
# A sample inside the workspace by a clearance stands for the samples of its segment that the
# TCP reaches in less time than it needs to cover that clearance at this many times the
# segment's executed peak speed (only the samples near a bound are evaluated: same result).
_WORKSPACE_SPEED_MARGIN = 1.01
# The executed motion may cross a workspace bound by this much at a sample [m]: JTC's
# interpolation wobbles by micrometres about a vertical segment on the boundary (a pick at
# exactly the workspace radius); this is the default knot_tolerance, the check's resolution.
_EXECUTED_WORKSPACE_TOLERANCE = 1e-4


@dataclass(frozen=True)
class PlannerConfig:
    """
    Everything the planner needs, validated as a whole.

    Attributes
    ----------
    geometry : DeltaGeometry
        Robot dimensions and joint position limits.
    joint_limits : JointLimits
        Joint velocity and acceleration limits.
    limits : CartesianLimits
        TCP speed, acceleration, jerk and the allowed acceleration step at T1/T2.
    arc : ArcPolicy
        How the ellipse is chosen.
    pick_clearance, place_clearance : float
        Vertical segments at pick and place [m].
    join : str
        ``'g2'`` (curvature-continuous transitions at T1 and T2, no
        acceleration step) or ``'paper'`` (the paper's path; the step is
        bounded by ``max_accel_jump``).
    join_tolerance : float
        Largest distance of the ``'g2'`` path from the paper's [m].
    profile : str
        ``'time_optimal'`` or ``'curvature'`` (the paper's).
    curvature_r : float
        The paper's proportionality coefficient r [rad/m], curvature profile only.
    knot_tolerance : float
        Largest TCP deviation of JTC's interpolation between knots [m].
    output_mode : str
        ``'knots'`` (fewest points within ``knot_tolerance``) or ``'samples'``
        (one point every ``sample_period``).
    sample_period : float
        Period of ``'samples'`` output [s].
    joint_names : tuple of str
        Names of the joints of arm 0, 1, 2.
    workspace : SafeWorkspace
        Where the TCP may go; every plan is checked against it as executed.

    """

    geometry: DeltaGeometry = field(default_factory=DeltaGeometry)
    joint_limits: JointLimits = field(default_factory=JointLimits)
    limits: CartesianLimits = field(default_factory=CartesianLimits)
    arc: ArcPolicy = field(default_factory=ArcPolicy)
    pick_clearance: float = default_of('pick_clearance')
    place_clearance: float = default_of('place_clearance')
    join: str = default_of('join')
    join_tolerance: float = default_of('join_tolerance')
    profile: str = default_of('profile')
    curvature_r: float = default_of('curvature_r')
    knot_tolerance: float = default_of('knot_tolerance')
    output_mode: str = default_of('output_mode')
    sample_period: float = default_of('sample_period')
    joint_names: tuple = default_of('joint_names')
    workspace: SafeWorkspace = field(default_factory=SafeWorkspace)

    def __post_init__(self):
        validate_fields(self)
        if self.profile == 'curvature' and self.join != 'paper':
            raise InvalidInputError(
                f"join: expected paper with profile curvature (the paper's node rule lives on "
                f'the ellipse), got {self.join!r}')
        if isinstance(self.joint_names, (str, bytes)) or not hasattr(self.joint_names,
                                                                     '__iter__'):
            # A string would be split into characters: 'abc' is not three joint names.
            raise InvalidInputError(
                f'joint_names: expected a list of 3 names, got {self.joint_names!r}')
        names = tuple(self.joint_names)
        if (len(names) != 3 or len(set(names)) != 3
                or not all(isinstance(name, str) and name for name in names)):
            raise InvalidInputError(
                f'joint_names: expected 3 distinct non-empty names, got {list(names)!r}')
        object.__setattr__(self, 'joint_names', names)

    @classmethod
    def from_flat(cls, values):
        """
        Build a config from flat setting names (``CORE_NAMES`` of :mod:`.settings`).

        Each name goes to the dataclass field its row feeds; missing names take their
        defaults; unknown names are an error.
        """
        unknown = sorted(set(values) - set(CORE_NAMES))
        if unknown:
            raise InvalidInputError(
                f'parameters: expected names among {", ".join(sorted(CORE_NAMES))}, '
                f'got unknown {", ".join(unknown)}')
        by_owner = {}
        for name, value in values.items():
            setting = SETTING_BY_NAME[name]
            by_owner.setdefault(setting.owner, {})[setting.attribute] = value
        # The sections (geometry, limits, ...) are the fields built by a default factory,
        # their class named by the rows' owner.
        parts = {item.name: item.default_factory(**by_owner.get(item.default_factory.__name__,
                                                                {}))
                 for item in fields(cls) if item.default_factory is not MISSING}
        return cls(**parts, **by_owner.get(cls.__name__, {}))


@dataclass(frozen=True, eq=False)
class LegPlan:
    """
    One planned leg: path, timed motion and joint trajectory.

    Attributes
    ----------
    path : PickPlacePath
        The geometric path.
    motion : TimedMotion
        The Cartesian motion along it (after any slow-down for joint limits).
    joint_trajectory : JointTrajectoryData
        Knots or samples for JTC, starting at t = 0.
    knot_positions : numpy.ndarray
        TCP positions of the trajectory points, shape (K, 3) [m].
    max_interpolation_error : float
        Largest TCP deviation of JTC's quintic interpolation from the motion [m].
    joint_peak_velocity, joint_peak_accel : float
        Largest |q_dot| [rad/s] and |q_ddot| [rad/s^2] of the motion.
    joint_slowdown : float
        Time-scaling factor applied to honour the joint acceleration limit and the
        executed limits (1 = none).
    executed : dict
        Peaks of what JTC executes (``EXECUTED_KEYS``; see :func:`executed_peaks`).

    """

    path: PickPlacePath
    motion: TimedMotion
    joint_trajectory: JointTrajectoryData
    knot_positions: np.ndarray
    max_interpolation_error: float
    joint_peak_velocity: float
    joint_peak_accel: float
    joint_slowdown: float
    executed: dict

    def summary(self):
        """Return the leg's numbers as a flat JSON-ready dict (SI, degrees marked ``_deg``)."""
        path, arc = self.path, self.path.arc
        motion_metrics = self.motion.metrics()
        result = {
            'l': arc.l if arc else None,
            'h': arc.h if arc else None,
            'phi_deg': math.degrees(arc.phi) if arc else None,
            'a': arc.a if arc else None,
            'b': arc.b if arc else None,
            'k': arc.k if arc else None,
            'theta_T1_deg': math.degrees(arc.theta_T1) if arc else None,
            'theta_T2_deg': math.degrees(arc.theta_T2) if arc else None,
            'arc_length_approx': arc.length_approx if arc else 0.0,
            'arc_length': arc.length if arc else 0.0,
            'path_length': path.length,
            'segment_lengths': path.segment_lengths.tolist(),
            'apex': path.apex.tolist(),
            'apex_height': arc.apex_height if arc else None,
            'min_radius_of_curvature': arc.min_radius if arc else None,
            'profile': self.motion.profile,
            'n_nodes': self.motion.n_nodes,
            'joint_slowdown': self.joint_slowdown,
            'planned.joint_peak_velocity': self.joint_peak_velocity,
            'planned.joint_peak_accel': self.joint_peak_accel,
            'executed.max_interpolation_error': self.max_interpolation_error,
            'n_points': int(self.joint_trajectory.time_from_start.size),
        }
        for key, value in motion_metrics.items():
            peak = key.startswith('peak_') or key.startswith('accel_jump_')
            result[f'planned.{key}' if peak else key] = value
        result.update({f'executed.{key}': value for key, value in self.executed.items()})
        return result


@dataclass(frozen=True, eq=False)
class CyclePlan:
    """
    A whole pick-and-place request: approach, dwell at pick, transfer, dwell at place.

    Attributes
    ----------
    legs : tuple of LegPlan
        (approach, transfer), or (transfer,) when the robot is already at the pick.
    joint_trajectory : JointTrajectoryData
        The chained trajectory, validated for JTC.
    metrics : collections.abc.Mapping
        Flat numbers for diagnostics (str -> float or str), computed on first access.
    end_position : numpy.ndarray
        TCP position at the end (the place), shape (3,).

    """

    legs: tuple
    joint_trajectory: JointTrajectoryData
    metrics: dict
    end_position: np.ndarray


@dataclass(frozen=True, eq=False)
class ApproachPlan:
    """
    An approach leg planned ahead of its cycle (see :func:`plan_approach`).

    Attributes
    ----------
    start, pick : numpy.ndarray
        Where the leg starts and ends (the pick) [m], shape (3,).
    config : PlannerConfig
        The configuration it was planned with.
    leg : LegPlan or None
        The leg; None when the start is on the pick (no approach).
    plan_time : float
        Time spent planning it [s].

    """

    start: np.ndarray
    pick: np.ndarray
    config: PlannerConfig
    leg: LegPlan | None
    plan_time: float

    def check_fits(self, start, pick, config, start_tolerance=0.0):
        """
        Raise unless this leg is the approach of a cycle from ``start`` to ``pick``.

        The pick and the configuration must be the same, the start within
        ``start_tolerance`` [m] of this leg's (the cycle then starts at this leg's).

        Raises
        ------
        InvalidInputError
            Naming what does not match: "expected X, got Y".

        """
        if not np.array_equal(self.pick, pick):
            raise InvalidInputError(
                f'approach: expected a leg to the pick {pick.tolist()}, got one to '
                f'{self.pick.tolist()}')
        distance = float(np.linalg.norm(self.start - start))
        if distance > start_tolerance:
            raise InvalidInputError(
                f'approach: expected a leg from within {start_tolerance:g} m of the start '
                f'{start.tolist()}, got one from {self.start.tolist()} ({distance:.6g} m away)')
        if self.config is not config and self.config != config:
            raise InvalidInputError(
                f'approach: expected a leg planned with the configuration {config!r}, got one '
                f'planned with {self.config!r}')


def plan_approach(start, pick, config=None):
    """
    Plan the approach leg of a cycle: from ``start`` (where the robot will be) to ``pick``.

    It lifts out of ``start`` as from a place and descends onto the pick (the clearances
    swapped); none when the start is on the pick. :func:`plan_cycle` plans the same leg, or
    takes this one.

    Returns
    -------
    ApproachPlan

    Raises
    ------
    EllipathError
        As :func:`plan_transfer`; ``workspace`` when the start is outside the safe workspace.

    """
    started = time.perf_counter()
    config = config or PlannerConfig()
    start, pick = require_point('start', start), require_point('pick', pick)
    return ApproachPlan(start, pick, config, _approach_leg(start, pick, config),
                        time.perf_counter() - started)


def _approach_leg(start, pick, config):
    """Return the approach LegPlan from ``start`` to ``pick`` (checked points), or None."""
    if np.linalg.norm(pick - start) <= _SAME_POINT:
        return None
    # The robot outside the safe workspace (moved there by hand) is not moved by a plan.
    config.workspace.check(start, name='start')
    # Lift out of wherever the robot is (as from a place), descend onto the pick.
    return plan_transfer(start, pick, config, pick_clearance=config.place_clearance,
                         place_clearance=config.pick_clearance, leg='approach')


def _check_reach_and_speed_cap(path, config):
    """
    Check reachability along the path and return the joint-velocity speed cap.

    The cap is ds/dt <= max_joint_velocity / max_i |dq_i/ds|, sampled at most
    ``_REACH_CHECK_SPACING`` apart and interpolated (with a margin) in between.
    """
    count = max(int(math.ceil(path.length / _REACH_CHECK_SPACING)) + 1, 3)
    s = np.linspace(0.0, path.length, count)
    position, tangent = path.rows_at_lengths(s)[:2]
    limit = _JOINT_CAP_MARGIN * config.joint_limits.max_velocity
    # The samples and, last, the apex (at rest: its rates are not used), in one pass.
    caps = joint_speed_caps(position, tangent, config.geometry, limit, rows=True,
                            extra=path.apex)
    if caps is None:
        # Named as always: the first of the samples and the apex out of reach, else the first
        # sample at a singularity.
        points = np.vstack((position.T, path.apex))
        q = inverse_kinematics(points, config.geometry, name='path point')[:-1]
        dq_ds = joint_velocities(points[:-1], q, tangent.T, config.geometry)
        caps = limit / np.maximum(largest_magnitude_per_row(dq_ds), 1e-12)

    def cap(query):
        return np.interp(query, s, caps)
    return cap


def _interpolation_error(motion, trajectory, config, per_segment=8):
    """Return the largest TCP deviation of JTC's quintic through ``trajectory``."""
    times = trajectory.time_from_start
    fractions = np.arange(1, per_segment + 1) / (per_segment + 1.0)
    t = (times[:-1, None] + np.diff(times)[:, None] * fractions).ravel()
    q, _, _ = quintic_interpolate(trajectory, t)
    tcp = forward_kinematics(q, config.geometry, name='interpolated q')
    return float(np.linalg.norm(tcp - motion.state_at(t)[0], axis=1).max())


def plan_transfer(pick, place, config=None, *, pick_clearance=None, place_clearance=None,
                  leg='transfer'):
    """
    Plan one leg from ``pick`` to ``place``: path, timing, kinematics, JTC points.

    Parameters
    ----------
    pick, place : array_like
        Start and end TCP positions in the base frame [m], shape (3,).
    config : PlannerConfig, optional
        Defaults when omitted.
    pick_clearance, place_clearance : float, optional
        Override the config's clearances (the approach leg lifts out of the
        previous place and descends onto the pick).
    leg : str
        Name of the leg in workspace errors (``'transfer'`` or ``'approach'``).

    Returns
    -------
    LegPlan

    Raises
    ------
    EllipathError
        ``invalid_input``, ``degenerate_geometry``, ``unreachable`` (naming the
        first point out of reach), ``workspace`` (naming the first point of the
        executed motion outside the safe workspace, and its time in the leg) or ``limit``.

    """
    config = config or PlannerConfig()
    # The end points first, so an unreachable pick or place is named as such.
    _check_ends(pick, place, config)
    path = plan_path(
        pick, place,
        config.pick_clearance if pick_clearance is None else pick_clearance,
        config.place_clearance if place_clearance is None else place_clearance,
        config.arc, config.join, config.join_tolerance)
    cap = _check_reach_and_speed_cap(path, config)
    timed = time_motion(path, config.limits, profile=config.profile, r=config.curvature_r,
                        speed_cap=cap)
    if timed.duration > _MAX_LEG_DURATION:
        raise LimitError(
            f'leg duration: expected at most {_MAX_LEG_DURATION:g} s, got {timed.duration:.4g} s '
            f'({config.profile} profile on a {path.length:.4g} m path); raise the limits or '
            f'choose another arc policy or profile')
    # One sample set of the motion serves the joint peaks, the knots and their positions.
    samples = MotionSamples.of(timed, config.geometry)
    peak_velocity, peak_accel = samples.joint_peaks()
    limits = config.joint_limits
    # Joint velocity is handled by the cap; joint acceleration (and any cap leak) by slowing
    # the whole leg down uniformly: q_dot scales with 1/f, q_ddot with 1/f**2. What JTC
    # executes (its quintic between the points) is then checked against every limit; points
    # are added where it breaks one (_joint_points), and what they cannot mend slows the leg
    # down by the measured excess (a few times at most). Slowing down by f needs no new
    # knots: the same knots with times x f, velocities / f and accelerations / f**2 are
    # those of the slower motion, and JTC's quintic through them is the same joint path
    # slowed down, so its peaks scale exactly (speed / f, acceleration / f**2, jerk / f**3).
    slowdown = max(1.0, peak_velocity / (_JOINT_LIMIT_SHARE * limits.max_velocity),
                   math.sqrt(peak_accel / (_JOINT_LIMIT_SHARE * limits.max_acceleration)))
    bounds = executed_bounds(config)
    motion = timed.scaled(slowdown) if slowdown > 1.0 else timed
    trajectory, error, table = _joint_points(motion, config, bounds,
                                             samples.scaled(slowdown, motion))
    for attempt in range(_SLOWDOWN_ATTEMPTS):
        excess = _excess_factor(table.max(axis=0) / bounds)
        try:
            check_joint_limits(trajectory, config.geometry, limits,
                               samples_per_segment=_QUINTIC_CHECK_SAMPLES, table=table)
        except LimitError:
            if attempt == _SLOWDOWN_ATTEMPTS - 1:
                raise
            excess = max(excess, _SLOWDOWN_STEP)
        if excess <= 1.0:
            break
        if attempt == _SLOWDOWN_ATTEMPTS - 1:
            raise LimitError(
                f'executed motion: expected JTC interpolation within the limits, got '
                f'{_describe_excess(table.max(axis=0), bounds)} after {_SLOWDOWN_ATTEMPTS} '
                'slow-downs')
        factor = max(excess * (1.0 + _SLOWDOWN_MARGIN), 1.0 + _SLOWDOWN_MARGIN)
        slowdown *= factor
        motion = timed.scaled(slowdown)
        if config.output_mode == 'samples':
            # Samples keep their period: sampled again.
            trajectory, error, table = _joint_points(motion, config, bounds,
                                                     samples.scaled(slowdown, motion))
        else:
            trajectory, table = _slowed_points(trajectory, table, factor)
    _check_executed_workspace(trajectory, config, leg, table[:, 0])
    knot_positions = samples.tcp_positions(trajectory.time_from_start / slowdown)
    executed = {key: float(value) for key, value in zip(EXECUTED_KEYS, table.max(axis=0))}
    return LegPlan(path, motion, trajectory, knot_positions, error, peak_velocity / slowdown,
                   peak_accel / slowdown ** 2, slowdown, executed)


def _check_ends(pick, place, config):
    """
    Raise unless ``pick`` and ``place`` are points the robot reaches within the workspace.

    Checked in the order the errors are named: the pick's coordinates and reach, the
    place's, then whether each is in the safe workspace; both points in one pass of each
    check (:func:`~.kinematics._ik`, :meth:`SafeWorkspace.contains`) when both are valid
    coordinates, the calls that name a failure only after one.
    """
    pick_point = require_coordinates('pick', pick)
    try:
        place_point = require_coordinates('place', place)
    except InvalidInputError:
        # An unreachable pick is named before the place.
        inverse_kinematics(pick_point, config.geometry, name='pick')
        raise
    ends = np.array((pick_point, place_point))
    if not _ik(ends, config.geometry)[1].any() and config.workspace.contains(ends).all():
        return
    inverse_kinematics(pick_point, config.geometry, name='pick')
    inverse_kinematics(place_point, config.geometry, name='place')
    config.workspace.check(pick, name='pick')
    config.workspace.check(place, name='place')


def _check_executed_workspace(trajectory, config, leg, speeds=None):
    """
    Raise WorkspaceError if JTC's interpolation of ``trajectory`` leaves the workspace.

    Checked at every ``_WORKSPACE_CHECK_PERIOD`` from the first point to the last; with
    ``speeds`` (S,), the executed TCP speed peak of each segment [m/s] (the first column of
    :func:`executed_table`), only the samples that the ones before them do not stand for
    (:func:`_first_outside`: same result).
    """
    times = trajectory.time_from_start
    count = max(int(math.ceil((times[-1] - times[0]) / _WORKSPACE_CHECK_PERIOD)) + 1, 2)
    # Without a finite speed, every sample is evaluated.
    speed_bounds = np.full(times.size - 1, np.inf)
    if speeds is not None:
        speed_bounds = _WORKSPACE_SPEED_MARGIN * np.asarray(speeds, dtype=float)
        speed_bounds[~np.isfinite(speed_bounds)] = np.inf
    workspace = config.workspace
    if _first_outside(times, trajectory.positions, trajectory.velocities,
                      trajectory.accelerations, count, speed_bounds,
                      *_kernel_geometry(config.geometry)[:5], workspace.radius, workspace.z_min,
                      workspace.z_max, workspace.box_table(),
                      _EXECUTED_WORKSPACE_TOLERANCE) < 0:
        return
    # Named as the vectorised check names it: the first sample out of reach or outside.
    t = np.linspace(times[0], times[-1], count)
    tcp = forward_kinematics(quintic_positions(trajectory, t), config.geometry,
                             name='interpolated q')
    workspace.check(tcp, name=f'executed TCP of the {leg} leg', times=t,
                    tolerance=_EXECUTED_WORKSPACE_TOLERANCE)


@kernel
def _first_outside(knots, positions, velocities, accelerations, count, speed_bounds, rx, ry,
                   offset, upper, forearm_sq, radius, z_min, z_max, boxes, tolerance):
    """
    Return the first of ``count`` samples whose executed TCP leaves the workspace, or -1.

    The samples are ``np.linspace(knots[0], knots[-1], count)``. The executed TCP is the
    forward kinematics of JTC's quintic through the knots; a pose that cannot be assembled
    counts as outside. A sample inside by a clearance (:func:`clearance`) stands for the
    later samples of its segment the TCP reaches in at most the clearance over
    ``speed_bounds`` of the segment (a bound of its speed there, inf for none): they are
    inside too. The other samples are evaluated one by one, in order.
    """
    c = np.empty((6, 3))
    segment = np.full(1, -1)
    first, final = knots[0], knots[knots.size - 1]
    step = (final - first) / (count - 1)
    row = 0
    while row < count:
        time = _sample_time(row, first, final, step, count)
        margin = _executed_clearance(knots, positions, velocities, accelerations, time, c,
                                     segment, rx, ry, offset, upper, forearm_sq, radius, z_min,
                                     z_max, boxes, tolerance)
        if margin < 0.0:
            return row
        if segment[0] < 0 or time >= final:
            row += 1
            continue
        # segment[0] is the segment of ``time``: its speed bound holds until its end.
        end = knots[segment[0] + 1]
        bound = speed_bounds[segment[0]]
        reach = end if bound * (end - time) <= margin else time + margin / bound
        covered = min(int((reach - first) / step), count - 1)
        while covered > row and _sample_time(covered, first, final, step, count) > reach:
            covered -= 1
        while (covered + 1 < count
               and _sample_time(covered + 1, first, final, step, count) <= reach):
            covered += 1
        row = max(covered, row) + 1
    return -1


@kernel(inline=True)
def _sample_time(row, first, final, step, count):
    """Return np.linspace(first, final, count)[row] (``step`` its spacing), bit for bit."""
    return final if row == count - 1 else row * step + first


@kernel
def _executed_clearance(knots, positions, velocities, accelerations, time, c, segment, rx, ry,
                        offset, upper, forearm_sq, radius, z_min, z_max, boxes, tolerance):
    """
    Return the workspace clearance of the executed TCP at ``time`` [m], -1 if not inside.

    -1 also if the pose cannot be assembled. ``c`` (6, 3) holds the quintic of segment
    ``segment[0]`` (-1: none yet), refilled when ``time`` is in another segment.
    """
    final = knots.size - 1
    if time >= knots[final] or final == 0:
        joints = (positions[final, 0], positions[final, 1], positions[final, 2])
    else:
        wanted = min(max(np.searchsorted(knots, time, side='right') - 1, 0), final - 1)
        if wanted != segment[0]:
            segment[0] = wanted
            _fill_quintic(knots[wanted + 1] - knots[wanted], positions, positions, velocities,
                          velocities, accelerations, accelerations, wanted, wanted + 1, c)
        x = max(time - knots[wanted], 0.0)
        joints = (_polynomial(c, 0, x, 0), _polynomial(c, 1, x, 0), _polynomial(c, 2, x, 0))
    status, x_, y_, z_ = _forward_point(
        math.cos(joints[0]), math.sin(joints[0]), math.cos(joints[1]), math.sin(joints[1]),
        math.cos(joints[2]), math.sin(joints[2]), rx, ry, offset, upper, forearm_sq)
    if status != _ASSEMBLED or not inside(x_, y_, z_, radius, z_min, z_max, boxes, tolerance):
        return -1.0
    return clearance(x_, y_, z_, radius, z_min, z_max, boxes, tolerance)


def _slowed_points(trajectory, table, factor):
    """Return ``trajectory`` and its executed ``table`` slowed down by ``factor``."""
    slowed = JointTrajectoryData(
        trajectory.joint_names, trajectory.time_from_start * factor, trajectory.positions,
        trajectory.velocities / factor, trajectory.accelerations / factor ** 2)
    # EXECUTED_KEYS order: TCP speed, acceleration, jerk, joint speed, acceleration.
    return slowed, table / np.array([factor, factor ** 2, factor ** 3, factor, factor ** 2])


def executed_bounds(config):
    """
    Return what the executed peaks must stay below, in the order of ``EXECUTED_KEYS``.

    With the paper's join the planned acceleration steps at T1 and T2, so any
    interpolation through points has a jerk there that grows without bound as
    the points come closer: that jerk is reported, not bounded.
    """
    limits, joints = config.limits, config.joint_limits
    jerk = _EXECUTED_JERK_SHARE * limits.max_jerk if config.join == 'g2' else math.inf
    return _EXECUTED_AIM * np.array([limits.max_speed, limits.max_accel, jerk,
                                    joints.max_velocity, joints.max_acceleration])


def _excess_factor(ratios):
    """Return the uniform slow-down that brings peaks at ``ratios`` of their bounds to 1."""
    speed, accel, jerk, joint_speed, joint_accel = ratios
    return float(max(speed, math.sqrt(accel), jerk ** (1.0 / 3.0), joint_speed,
                     math.sqrt(joint_accel)))


def _describe_excess(peaks, bounds):
    return ', '.join(f'{key} {peak:.6g} (bound {bound:.6g})'
                     for key, peak, bound in zip(EXECUTED_KEYS, peaks, bounds) if peak > bound)


def _joint_points(motion, config, bounds, samples=None):
    """
    Return the JTC points of ``motion``, their TCP deviation and executed peaks per segment.

    Knots (``minimal_knots``) bound the position deviation of JTC's interpolation; its
    speed, acceleration and jerk can still exceed the planned ones: a quintic cannot follow
    a step of the jerk, and reaches up to 1.7 times the true jerk across one. So every
    segment whose executed peaks (:func:`executed_peaks`) break ``bounds`` and exceed the
    planned motion's there by more than ``_QUINTIC_EXCESS`` gets points at the jerk steps
    inside it of at least ``_JERK_STEP_SHARE`` of the limit, or at its middle (the sample
    nearest to it) if it has none, for up to ``_KNOT_ROUNDS`` rounds and while a round
    lowers an exceeded peak. Of the knots and each round, the points whose executed peaks
    need the least uniform slow-down (:func:`_excess_factor`) are returned: a round may lower
    one exceeded peak and raise another. The segments that a round's points make are kept
    within the knot tolerance (halved up to ``_MEND_HALVINGS`` times, in the same compiled
    call as they are made: :func:`~ellipath_ros.core.knots._split_segments`); a round whose
    segments still fail is not returned. Samples output is checked, not changed. The table
    (S, 5) has the peaks of each segment in ``EXECUTED_KEYS`` order. ``samples``
    (:class:`MotionSamples` of ``motion``) are taken when given, else made here.
    """
    geometry = config.geometry
    if config.output_mode == 'samples':
        trajectory = sample_joint_trajectory(motion, geometry, config.sample_period,
                                             config.joint_names)
        error = _interpolation_error(motion, trajectory, config)
        return trajectory, error, executed_table(trajectory, geometry)
    samples = MotionSamples.of(motion, geometry) if samples is None else samples
    trajectory, error = minimal_knots(motion, geometry, config.joint_names,
                                      config.knot_tolerance, samples=samples)
    steps = None
    table = executed_table(trajectory, geometry)
    worst = table.max(axis=0) / bounds
    # The largest deviation of the segments made so far (those a later round splits included:
    # an upper bound), and the points whose peaks need the least slow-down so far (the first
    # of equals) with theirs.
    deviation = error
    least = (_excess_factor(worst), trajectory, table, deviation)
    for _ in range(_KNOT_ROUNDS):
        times = trajectory.time_from_start
        # Points mend what the quintic adds to the motion, not what the motion itself has.
        broken = samples.segments_beyond(times, table, bounds, 1.0 + _QUINTIC_EXCESS)
        if broken.size == 0:
            break
        if steps is None:
            # Only a leg with a broken segment needs its jerk steps.
            step_times, step_sizes = motion.jerk_steps()
            steps = step_times[step_sizes >= _JERK_STEP_SHARE * config.limits.max_jerk]
        trajectory, made = _split_segments(samples, trajectory, steps, broken,
                                           config.knot_tolerance, _KNOT_MIN_GAP, _MEND_HALVINGS)
        deviation = max(deviation, made)
        table = executed_table(trajectory, geometry, (times, table))
        ratios = table.max(axis=0) / bounds
        excess = _excess_factor(ratios)
        if excess < least[0] and deviation <= _SAFETY * config.knot_tolerance:
            least = (excess, trajectory, table, deviation)
        # When a round lowers no exceeded peak, only the slow-down that follows can.
        if not (ratios < worst)[worst > 1.0].any():
            break
        worst = ratios
    return least[1], least[3], least[2]


def _hold(trajectory, seconds):
    """
    Append a rest point ``seconds`` after the last one (a dwell).

    A dwell under a nanosecond, the resolution of the message's times, adds nothing: its
    point would fall on the last one's time (1e-79 s did), which JTC refuses. A link of a
    chain, as :func:`_concatenate`.
    """
    if seconds < 1e-9:
        return trajectory
    return _concatenate(trajectory, JointTrajectoryData._chained(
        trajectory.joint_names, np.array([0.0, seconds]),
        np.repeat(trajectory.positions[-1:], 2, axis=0), np.zeros((2, 3)), np.zeros((2, 3))))


def _concatenate(first, second):
    """
    Chain ``second`` after ``first``; its first point (equal to first's last) is dropped.

    A link of a chain of checked trajectories (legs, rests): not checked again, the chain's
    end is checked whole, on whole nanoseconds (``validate_jtc``).
    """
    offset = first.time_from_start[-1]
    return JointTrajectoryData._chained(
        first.joint_names,
        np.concatenate((first.time_from_start, offset + second.time_from_start[1:])),
        np.vstack((first.positions, second.positions[1:])),
        np.vstack((first.velocities, second.velocities[1:])),
        np.vstack((first.accelerations, second.accelerations[1:])))


def plan_cycle(start, pick, place, config=None, pick_dwell=0.0, place_dwell=0.0,
               approach=None, start_tolerance=0.0):
    """
    Plan the motion from where the robot is, through the pick, to the place.

    Parameters
    ----------
    start : array_like
        Current TCP position [m], shape (3,).
    pick, place : array_like
        Pick and place TCP positions [m], shape (3,).
    config : PlannerConfig, optional
        Defaults when omitted.
    pick_dwell, place_dwell : float
        Rest at the pick and at the place [s], in [0, 10].
    approach : ApproachPlan, optional
        The approach leg planned ahead (:func:`plan_approach`) for this ``pick`` and
        ``config``: the cycle then starts at its start, and the plan is the one planned from
        there in one go, bit for bit. Planned here when omitted.
    start_tolerance : float
        Largest distance of ``approach``'s start from ``start`` [m].

    Returns
    -------
    CyclePlan
        Its metrics' ``plan_time`` is this call's; ``approach.plan_time`` is the approach
        leg's, ``approach.preplanned`` says whether it was planned ahead.

    """
    started = time.perf_counter()
    config = config or PlannerConfig()
    start, pick, place, pick_dwell, place_dwell = _cycle_inputs(
        start, pick, place, pick_dwell, place_dwell)
    if approach is not None:
        approach.check_fits(start, pick, config, start_tolerance)
    transfer = plan_transfer(pick, place, config)
    preplanned = approach is not None
    if not preplanned:
        approach = plan_approach(start, pick, config)
    legs = (transfer,)
    trajectory = transfer.joint_trajectory
    if approach.leg is not None:
        legs = (approach.leg, transfer)
        trajectory = _concatenate(_hold(approach.leg.joint_trajectory, pick_dwell), trajectory)
    elif pick_dwell > 0.0:
        trajectory = _concatenate(_hold(_rest_point(trajectory), pick_dwell), trajectory)
    trajectory = on_whole_nanoseconds(_hold(trajectory, place_dwell))
    validate_jtc(trajectory, config.joint_names)
    plan_time = time.perf_counter() - started
    return CyclePlan(legs, trajectory, _LazyMetrics(functools.partial(
        _cycle_metrics, legs, trajectory, plan_time, approach, preplanned)), place.copy())


def _cycle_inputs(start, pick, place, pick_dwell, place_dwell):
    """Return the checked (start, pick, place, pick_dwell, place_dwell) of a cycle request."""
    return (require_point('start', start), require_point('pick', pick),
            require_point('place', place), validate('pick_dwell', pick_dwell),
            validate('place_dwell', place_dwell))


def _cycle_metrics(legs, trajectory, plan_time, approach, preplanned):
    """Return the flat diagnostics of a cycle: each leg's summary, prefixed, and the totals."""
    named = [('transfer', legs[-1])] + ([('approach', legs[0])] if len(legs) == 2 else [])
    metrics = {}
    for name, leg in named:
        metrics.update({f'{name}.{key}': value for key, value in leg.summary().items()
                        if isinstance(value, (int, float, str))})
    metrics.update({
        'duration': float(trajectory.time_from_start[-1]),
        'n_points': int(trajectory.time_from_start.size),
        'executed.max_interpolation_error': max(leg.max_interpolation_error for leg in legs),
        'planned.joint_peak_velocity': max(leg.joint_peak_velocity for leg in legs),
        'planned.joint_peak_accel': max(leg.joint_peak_accel for leg in legs),
        'plan_time': plan_time,
    })
    if approach.leg is not None:
        metrics.update({'approach.plan_time': approach.plan_time,
                        'approach.preplanned': 'true' if preplanned else 'false'})
    return metrics


class _LazyMetrics(Mapping):
    """
    A read-only mapping built on first access.

    The metrics are for diagnostics only (the motion does not depend on them),
    and the legs' summaries sample every motion again: computed when read,
    after the trajectory is on its way, they stay out of the planning latency.
    """

    def __init__(self, build):
        self._build = build
        self._values = None

    def _computed(self):
        if self._values is None:
            self._values = self._build()
        return self._values

    def __getitem__(self, key):
        return self._computed()[key]

    def __iter__(self):
        return iter(self._computed())

    def __len__(self):
        return len(self._computed())


def _rest_point(trajectory):
    """Return the first point of ``trajectory`` alone (the robot at rest there)."""
    return JointTrajectoryData(trajectory.joint_names, trajectory.time_from_start[:1],
                               trajectory.positions[:1], trajectory.velocities[:1],
                               trajectory.accelerations[:1])
