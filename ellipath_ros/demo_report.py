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
The report of ``ellipath demo``: what the robot executes, judged without ROS.

The client (:mod:`ellipath_ros.demo`) records what it sent and what came back: the answer of
the node to every pair (:class:`PairOutcome`) and every trajectory message with its header
stamp and the time it arrived (:class:`ReceivedTrajectory`). :func:`evaluate_run` replays the
trajectories, in arrival order and at their arrival times, through the emulation of Jazzy's
joint_trajectory_controller (:class:`~ellipath_ros.core.controller.JazzyJtcEmulator`, 1 kHz,
perfect tracking, velocity state interface) and judges the executed motion, that is the
commands the controller writes:

* every message passes ``validate_jtc`` and the controller accepts it;
* the executed TCP stays within ``PATH_TOLERANCE`` (0.1 mm) of the planned paths, the forward
  kinematics of JTC's interpolation of each trajectory on its own;
* every pick and place of the planned pairs is visited, in the order sent;
* the executed joint commands stay within the joint position, velocity and acceleration
  limits, and the TCP within the node's safe workspace (``config.workspace``, judged by
  :meth:`~ellipath_ros.core.workspace.SafeWorkspace.check` itself);
* each deliberately bad pair is rejected with the kind expected of it
  (``PairOutcome.expected_rejection``), every other pair is planned.

Throughput and the hand-over gaps come from the executed timeline, not from the planned
durations; both are printed. :func:`format_report` prints the table and the summary.
"""

from dataclasses import dataclass
from dataclasses import field
from dataclasses import replace
import math

from ellipath_ros.core.controller import distance_to_paths
from ellipath_ros.core.controller import executed_tcp
from ellipath_ros.core.controller import JazzyJtcEmulator
from ellipath_ros.core.controller import planned_tcp_path
from ellipath_ros.core.controller import visit_times
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.errors import LimitError
from ellipath_ros.core.errors import WorkspaceError
from ellipath_ros.core.joint_trajectory import check_joint_limits
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import TrajectoryRejectedError
from ellipath_ros.core.joint_trajectory import validate_jtc
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.kinematics import JointLimits
import numpy as np

# The executed TCP must stay this close to the planned paths, and pass this close to every
# pick and place [m] (issue 9: 0.1 mm).
PATH_TOLERANCE = 1e-4
VISIT_TOLERANCE = 1e-4
# The emulated controller: 1 kHz, with a velocity state interface (usual for servo drives).
CONTROL_PERIOD = 0.001  # s
VELOCITY_STATE = True
# Replay this long past the predicted end of the last trajectory [s].
REPLAY_MARGIN = 0.05
# Relative slack on the joint limits, for rounding only.
LIMIT_SLACK = 1e-6
# Keys of the node's OK status (the planner's CyclePlan.metrics).
PHI_KEY = 'transfer.phi_deg'
APEX_KEY = 'transfer.apex_height'
PLAN_TIME_KEY = 'plan_time'
DURATION_KEY = 'duration'
_MM = 1e3
_MS = 1e3
# Why a replaced trajectory is a failure, printed with it.
REPLACEMENT_NOTE = (
    "Jazzy's joint_trajectory_controller replaces the running trajectory with a newly "
    'received one at its next control cycle, whatever its header.stamp, and splines from '
    'the current state to its first point: a trajectory must be published only once the '
    'previous one has ended')


@dataclass(frozen=True)
class ReceivedTrajectory:
    """
    One trajectory message as the client received it.

    Attributes
    ----------
    data : JointTrajectoryData or None
        Its points (None when they could not be read).
    stamp : float
        ``header.stamp`` [s] (0 = start on receipt).
    receive_time : float
        When it arrived [s], on the clock of the stamps (the system clock).
    problems : tuple of str
        What is wrong with the message beyond its points (frame, effort, malformed).

    """

    data: JointTrajectoryData | None
    stamp: float
    receive_time: float
    problems: tuple = ()


@dataclass
class PairOutcome:
    """
    One pick/place pair as sent, and the node's answer (filled in by the client).

    Attributes
    ----------
    index : int
        0-based number of the pair.
    pick, place : numpy.ndarray
        The pair [m], shape (3,).
    expected_rejection : str or None
        For a deliberately bad pair, the ``kind`` of the rejection expected of the node
        (``'unreachable'``, ``'workspace'``); None for a good pair.
    sent_time : float
        When its place was sent [s], system clock.
    level : str or None
        Level of the node's answer: ``'OK'`` (planned) or ``'ERROR'`` (rejected); None when
        no answer came.
    message : str
        The answer's message (the rejection reason).
    values : dict
        The answer's key/values.
    round_trip : float
        Place sent to answer received [s].

    """

    index: int
    pick: np.ndarray
    place: np.ndarray
    expected_rejection: str = None
    sent_time: float = math.nan
    level: str = None
    message: str = ''
    values: dict = field(default_factory=dict)
    round_trip: float = math.nan

    def number(self, key):
        """Return the node's value ``key`` as a float (NaN when missing or not a number)."""
        try:
            return float(self.values[key])
        except (KeyError, TypeError, ValueError):
            return math.nan


@dataclass(frozen=True)
class PairRow:
    """
    The verdict on one pair and what the controller did with its trajectory.

    Attributes
    ----------
    outcome : PairOutcome
        The pair and the node's answer.
    verdict : str
        ``'ok'``, ``'rejected_expected'``, ``'rejected_unexpected'``, ``'not_rejected'``
        (the bad pair was planned), ``'invalid'`` (its message fails a check),
        ``'not_executed'`` (planned, but not executed as planned), ``'missing'`` (planned,
        no trajectory came) or ``'timeout'`` (no answer).
    reason : str
        Why, when the verdict is not ``'ok'``.
    start : float
        Executed: when the controller took its trajectory up, from the first pair sent [s].
    gap : float
        Executed: idle time between the end of the previous trajectory and the start of
        this one [s]; negative when this one replaced the previous one before its end (then
        minus the time the previous one had left).
    deviation : float
        Executed: largest distance of the TCP from the planned paths while its trajectory
        commanded the robot [m].

    """

    outcome: PairOutcome
    verdict: str
    reason: str = ''
    start: float = math.nan
    gap: float = math.nan
    deviation: float = math.nan


@dataclass(frozen=True)
class RunReport:
    """
    The judged run: rows, measured figures and the failed checks.

    Attributes
    ----------
    rows : tuple of PairRow
        One per pair sent, in order.
    figures : dict
        Measured values, each key saying planned or executed (see :func:`evaluate_run`).
    failures : tuple of str
        One line per failed check; empty when the run passed.
    timed_out : bool
        Whether an answer or a trajectory did not come in time.

    """

    rows: tuple
    figures: dict
    failures: tuple
    timed_out: bool = False

    @property
    def passed(self):
        """Return True when no check failed and nothing timed out."""
        return not self.failures and not self.timed_out


class _Replay:
    """The received trajectories run through the emulated controller, and what it did."""

    def __init__(self, trajectories, home_position, config, start_time):
        geometry = config.geometry
        self.emulator = JazzyJtcEmulator(
            config.joint_names, CONTROL_PERIOD, VELOCITY_STATE, start_time,
            inverse_kinematics(np.asarray(home_position, dtype=float), geometry,
                               name='home_position'))
        self.accepted = {}  # trajectory number -> emulator index
        self.rejections = {}  # trajectory number -> why the controller refuses it
        end = start_time
        order = sorted(range(len(trajectories)), key=lambda k: trajectories[k].receive_time)
        for number in order:
            received = trajectories[number]
            if received.data is None:
                continue
            try:
                self.accepted[number] = self.emulator.receive(
                    received.data, received.stamp, received.receive_time)
            except TrajectoryRejectedError as error:
                self.rejections[number] = str(error)
                continue
            begin = received.stamp or received.receive_time + CONTROL_PERIOD
            end = max(end, begin + received.data.duration)
        self.emulator.run_until(end + REPLAY_MARGIN)
        self.samples = self.emulator.samples()
        self.tcp = executed_tcp(self.samples, geometry)
        paths = [planned_tcp_path(trajectories[number].data, geometry)
                 for number in self.accepted]
        self.deviation = (distance_to_paths(self.tcp.positions, paths) if paths
                          else np.zeros(self.samples.times.size))
        self.timeline = self._timeline(trajectories)
        self.gaps, self.cut_short = self._hand_overs()

    def _timeline(self, trajectories):
        """Per trajectory taken up: (pickup, motion start, planned end) [s], executed."""
        timeline = {}
        for number, index in self.accepted.items():
            received = trajectories[number]
            pickup = float(self.samples.pickup_times[index])
            if math.isnan(pickup):
                continue  # overwritten by a later message before any cycle took it up
            begin = received.stamp or pickup
            knots = received.data.time_from_start
            timeline[number] = (pickup, max(pickup, begin + knots[0]), begin + knots[-1])
        return timeline

    def _hand_overs(self):
        """
        Return the gaps and the cuts of the hand-overs, by trajectory number [s].

        Gap: per trajectory after the first, the idle time since the previous one ended;
        negative when it was taken up before that end (it then replaced the previous one
        while running), minus the time that was left. Cut: per trajectory replaced while
        running, the time it had left.
        """
        ordered = sorted(self.timeline.items(), key=lambda item: item[1][0])
        gaps, cuts = {}, {}
        for (previous, (_, _, end)), (number, (pickup, start, _)) in zip(ordered, ordered[1:]):
            if pickup < end:
                gaps[number], cuts[previous] = pickup - end, end - pickup
            else:
                gaps[number] = start - end
        return gaps, cuts

    def rows_of(self, number):
        """Boolean mask of the samples commanded by trajectory ``number``."""
        if number not in self.accepted:
            return np.zeros(self.samples.times.size, dtype=bool)
        return self.samples.source == self.accepted[number]


# What the executed jerk means with each join (the planner bounds it only with g2).
_JERK_NOTE = {
    'g2': 'the planner keeps it within 1.10 times the limit',
    'paper': 'unbounded at the joins: the paper path steps the acceleration there',
}


def evaluate_run(outcomes, trajectories, home_position, config, start_time, timed_out=False):
    """
    Judge a demo run from what was sent and received.

    Parameters
    ----------
    outcomes : sequence of PairOutcome
        Every pair sent, in order, with the node's answer.
    trajectories : sequence of ReceivedTrajectory
        Every trajectory received, in arrival order. The k-th belongs to the k-th planned
        pair (the node answers pairs in order).
    home_position : array_like, shape (3,)
        Where the robot stands before the first trajectory [m].
    config : ellipath_ros.core.planner.PlannerConfig
        The node's configuration (joint names, geometry, limits).
    start_time : float
        When the first pair was sent [s], system clock; the replay starts there.
    timed_out : bool
        Whether the client gave up waiting for an answer or a trajectory.

    Returns
    -------
    RunReport
        Figures: ``planned_duration_total`` [s], ``planned_picks_per_min``,
        ``plan_latency_mean``/``_max`` [s], ``round_trip_mean`` [s]; executed:
        ``executed_cycles`` (pairs whose pick and place were visited in order),
        ``executed_span`` [s], ``executed_picks_per_min``, ``executed_gap_max``/``_p50``
        [s] (over every hand-over; negative: a replacement), ``executed_replacements``
        (trajectories replaced while running) and ``executed_cut_max`` [s],
        ``executed_deviation_max`` [m], ``executed_visits`` and ``visit_targets``,
        ``executed_peak_tcp_speed``/``_accel``/``_jerk`` (finite differences at 1 kHz),
        ``executed_peak_joint_velocity``/``_accel``, ``executed_workspace_clear``
        (the executed TCP inside ``config.workspace`` throughout).

    """
    failures = []
    planned = [outcome for outcome in outcomes if outcome.level == 'OK']
    owner = {number: planned[number] for number in range(min(len(planned), len(trajectories)))}
    if len(trajectories) > len(planned):
        failures.append(f'{len(trajectories) - len(planned)} trajectories more than pairs '
                        f'planned ({len(trajectories)} received, {len(planned)} planned)')
    message_problems = {number: _message_problems(received, config)
                        for number, received in enumerate(trajectories)}
    replay = _Replay(trajectories, home_position, config, start_time)
    for number, why in replay.rejections.items():
        message_problems[number] = message_problems[number] + (f'JTC rejects it: {why}',)
    figures = _planned_figures(planned, outcomes)
    executed = _executed_figures(replay, owner, config, failures)
    figures.update(executed)
    rows = []
    number_of = {id(outcome): number for number, outcome in owner.items()}
    for outcome in outcomes:
        number = number_of.get(id(outcome))
        row = _judge(outcome, number, message_problems.get(number, ()), replay)
        rows.append(row)
        if row.verdict not in ('ok', 'rejected_expected'):
            failures.append(f'pair {outcome.index + 1}: {STATUS_LABELS[row.verdict]}'
                            + (f': {row.reason}' if row.reason else ''))
    return RunReport(tuple(rows), figures, tuple(failures), timed_out)


def _message_problems(received, config):
    """Return what is wrong with one trajectory message, before execution."""
    problems = received.problems
    if received.data is None:
        return problems
    try:
        validate_jtc(received.data, expect_names=config.joint_names)
    except EllipathError as error:
        problems = problems + (f'validate_jtc: {error}',)
    return problems


def _planned_figures(planned, outcomes):
    """Return the planned figures (durations from the node's OK statuses)."""
    durations = [outcome.number(DURATION_KEY) for outcome in planned]
    durations = [value for value in durations if math.isfinite(value)]
    latencies = [outcome.number(PLAN_TIME_KEY) for outcome in planned]
    latencies = [value for value in latencies if math.isfinite(value)]
    round_trips = [outcome.round_trip for outcome in outcomes
                   if math.isfinite(outcome.round_trip)]
    total = float(sum(durations))
    return {
        'planned_duration_total': total,
        'planned_picks_per_min': 60.0 * len(durations) / total if total > 0 else math.nan,
        'plan_latency_mean': float(np.mean(latencies)) if latencies else math.nan,
        'plan_latency_max': float(np.max(latencies)) if latencies else math.nan,
        'round_trip_mean': float(np.mean(round_trips)) if round_trips else math.nan,
    }


def _executed_figures(replay, owner, config, failures):
    """Measure the executed motion; append the failed executed checks to ``failures``."""
    samples, tcp, deviation = replay.samples, replay.tcp, replay.deviation
    figures = {}
    gaps = list(replay.gaps.values())
    cuts = list(replay.cut_short.values())
    figures['executed_gap_max'] = max(gaps) if gaps else math.nan
    figures['executed_gap_p50'] = float(np.median(gaps)) if gaps else math.nan
    figures['executed_replacements'] = len(cuts)
    figures['executed_cut_max'] = max(cuts) if cuts else math.nan

    # Visits: the pick and the place of every planned pair, in the order sent.
    targets = [point for number in sorted(owner)
               for point in (owner[number].pick, owner[number].place)]
    visits = (visit_times(samples.times, tcp.positions, targets, VISIT_TOLERANCE)
              if targets else np.zeros(0))
    figures['executed_visits'] = int(np.isfinite(visits).sum())
    figures['visit_targets'] = len(targets)
    completed = int(np.isfinite(visits[1::2]).sum()) if targets else 0
    figures['executed_cycles'] = completed
    if replay.timeline:
        span = (max(end for _, _, end in replay.timeline.values())
                - min(start for _, start, _ in replay.timeline.values()))
        figures['executed_span'] = span
        figures['executed_picks_per_min'] = 60.0 * completed / span if span > 0 else math.nan
    else:
        figures['executed_span'] = figures['executed_picks_per_min'] = math.nan
    if len(targets) and not np.isfinite(visits).all():
        missing = int(np.argmax(~np.isfinite(visits)))
        kind = 'pick' if missing % 2 == 0 else 'place'
        failures.append(
            f'executed: {figures["executed_visits"]} of {len(targets)} picks and places '
            f'visited in order; the {kind} of planned pair {missing // 2 + 1} '
            f'({mm_text(targets[missing])} mm) is never reached within '
            f'{VISIT_TOLERANCE * _MM:g} mm after the one before it')

    finite = np.isfinite(deviation)
    worst = int(np.argmax(np.where(finite, deviation, -1.0))) if finite.any() else 0
    figures['executed_deviation_max'] = float(deviation[worst]) if finite.any() else math.nan
    if not finite.all():
        failures.append('executed: the joint command cannot be assembled into a robot at '
                        f't={samples.times[int(np.argmin(finite))] - samples.times[0]:.3f} s')
    if figures['executed_deviation_max'] > PATH_TOLERANCE:
        when = samples.times[worst] - samples.times[0]
        message = (f'executed TCP leaves the planned paths by '
                   f'{figures["executed_deviation_max"] * _MM:.2f} mm (limit '
                   f'{PATH_TOLERANCE * _MM:g} mm) at t={when:.3f} s')
        if cuts:
            message += (f'; {len(cuts)} trajectories were replaced while running (up to '
                        f'{max(cuts) * _MS:.0f} ms before their end). {REPLACEMENT_NOTE}')
        failures.append(message)

    figures['executed_peak_tcp_speed'] = tcp.peak_speed
    figures['executed_peak_tcp_accel'] = tcp.peak_acceleration
    figures['executed_peak_tcp_jerk'] = tcp.peak_jerk
    figures['executed_peak_joint_velocity'] = float(np.abs(samples.velocities).max())
    figures['executed_peak_joint_accel'] = float(np.abs(samples.accelerations).max())
    failures.extend(_limit_failures(samples, config))
    figures['executed_workspace_clear'] = True
    workspace_failure = _workspace_failure(samples.times, tcp.positions, config.workspace)
    if workspace_failure is not None:
        figures['executed_workspace_clear'] = False
        failures.append(workspace_failure)
    return figures


def _limit_failures(samples, config):
    """Return the first joint limit the executed command breaks, as a failure line."""
    geometry, limits = config.geometry, config.joint_limits
    span = geometry.joint_max - geometry.joint_min
    # The relaxed bounds stay within the ranges the dataclasses accept.
    relaxed_geometry = replace(
        geometry, joint_min=max(-math.pi, geometry.joint_min - LIMIT_SLACK * span),
        joint_max=min(math.pi, geometry.joint_max + LIMIT_SLACK * span))
    relaxed_limits = JointLimits(min(1e3, limits.max_velocity * (1.0 + LIMIT_SLACK)),
                                 min(1e5, limits.max_acceleration * (1.0 + LIMIT_SLACK)))
    command = JointTrajectoryData(config.joint_names, samples.times - samples.times[0],
                                  samples.positions, samples.velocities,
                                  samples.accelerations)
    try:
        check_joint_limits(command, relaxed_geometry, relaxed_limits)
    except LimitError as error:
        return [f'executed joint command: {error}']
    return []


def _workspace_failure(times, tcp, workspace):
    """
    Return a failure line if the executed TCP leaves the node's safe workspace, else None.

    Judged by :meth:`SafeWorkspace.check` itself, at its default tolerance (the planner's
    check of the executed motion), naming the first offending sample and its time.
    """
    try:
        workspace.check(tcp, name='executed TCP', times=times - times[0])
    except WorkspaceError as error:
        return str(error)
    return None


def _judge(outcome, number, problems, replay):
    """
    Return the row of one pair.

    ``number`` is its trajectory's (None without one), ``problems`` those of its message.
    Its pick and place must be reached while its own trajectory commands the robot.
    """
    if outcome.level is None:
        return PairRow(outcome, 'timeout', 'no answer from the node')
    expected = outcome.expected_rejection
    if expected is not None:
        if outcome.level == 'OK':
            return PairRow(outcome, 'not_rejected', f'expected a rejection ({expected}) of '
                           f'{mm_text(outcome.pick)} -> {mm_text(outcome.place)} mm')
        kind = outcome.values.get('kind')
        verdict = 'rejected_expected' if kind == expected else 'rejected_unexpected'
        return PairRow(outcome, verdict, outcome.message)
    if outcome.level != 'OK':
        return PairRow(outcome, 'rejected_unexpected', outcome.message)
    if number is None:
        return PairRow(outcome, 'missing', 'planned, but no trajectory arrived')
    start = gap = deviation = math.nan
    rows = replay.rows_of(number)
    if number in replay.timeline:
        pickup = replay.timeline[number][0]
        start = pickup - replay.samples.times[0]
        gap = replay.gaps.get(number, math.nan)
        deviation = float(np.nanmax(replay.deviation[rows])) if rows.any() else math.nan
    if problems:
        return PairRow(outcome, 'invalid', '; '.join(problems), start, gap, deviation)
    reasons, notes = [], []
    pick_visit, place_visit = (
        visit_times(replay.samples.times[rows], replay.tcp.positions[rows],
                    [outcome.pick, outcome.place], VISIT_TOLERANCE) if rows.any()
        else (math.nan, math.nan))
    if not math.isfinite(pick_visit):
        reasons.append('pick not reached')
    elif not math.isfinite(place_visit):
        reasons.append('place not reached')
    if deviation > PATH_TOLERANCE:
        reasons.append(f'left the planned path by {deviation * _MM:.2f} mm')
    # A hand-over before the end is judged by what it does to the path (deviation, visits):
    # one that continues the running motion exactly is allowed (issue 9).
    if number in replay.cut_short:
        notes.append(f'replaced by the next trajectory {replay.cut_short[number] * _MS:.1f} '
                     'ms before its end')
    if gap < 0.0:
        notes.append(f'took over while the previous trajectory ran ({-gap * _MS:.1f} ms '
                     'left)')
    if reasons:
        return PairRow(outcome, 'not_executed', '; '.join(reasons + notes), start, gap,
                       deviation)
    return PairRow(outcome, 'ok', '; '.join(notes), start, gap, deviation)


def mm_text(point):
    """Format a point [m] as whole millimetres, '(x, y, z)'."""
    return '(' + ','.join(f'{value * _MM:4.0f}' for value in np.asarray(point)) + ')'


STATUS_LABELS = {
    'ok': 'OK',
    'rejected_expected': 'REJECTED (expected)',
    'rejected_unexpected': 'REJECTED (unexpected)',
    'not_rejected': 'PLANNED (bad pair)',
    'invalid': 'INVALID',
    'not_executed': 'NOT EXECUTED AS PLANNED',
    'missing': 'NO TRAJECTORY',
    'timeout': 'TIMEOUT',
}

# Table columns: title, unit, width, format, value of a PairRow (NaN prints as '-').
_COLUMNS = (
    ('phi', '[deg]', 5, '.1f', lambda row: row.outcome.number(PHI_KEY)),
    ('apex', '[mm]', 5, '.1f', lambda row: row.outcome.number(APEX_KEY) * _MM),
    ('planned', '[ms]', 7, '.1f', lambda row: row.outcome.number(DURATION_KEY) * _MS),
    ('plan', '[ms]', 6, '.1f', lambda row: row.outcome.number(PLAN_TIME_KEY) * _MS),
    ('start', '[s]', 6, '.3f', lambda row: row.start),
    ('gap', '[ms]', 7, '.1f', lambda row: row.gap * _MS),
    ('dev', '[mm]', 7, '.3f', lambda row: row.deviation * _MM),
)
_PAIR_WIDTH = 36


def table_header():
    """Return the header lines of the pair table, saying which columns are executed."""
    legend = ('planned: phi, apex, planned duration, plan (planning time); executed (the '
              'controller emulated): start (take-up since the first pair was sent), gap '
              '(idle since the previous trajectory ended; negative: it was cut short), dev '
              '(largest TCP distance from the planned paths)\n')
    titles = [f'{"#":>4}  {"pick -> place":<{_PAIR_WIDTH}}']
    units = [f'{"":>4}  {"[mm]":<{_PAIR_WIDTH}}']
    for title, unit, width, _, _ in _COLUMNS:
        titles.append(f'{title:>{width}}')
        units.append(f'{unit:>{width}}')
    return legend + ' '.join(titles) + '  status\n' + ' '.join(units) + '\n'


def table_row(row):
    """Return the table line of one pair."""
    outcome = row.outcome
    cells = [f'{outcome.index + 1:>4}  '
             f'{mm_text(outcome.pick) + " -> " + mm_text(outcome.place):<{_PAIR_WIDTH}}']
    for _, _, width, spec, value_of in _COLUMNS:
        value = value_of(row)
        cells.append(f'{value:>{width}{spec}}' if math.isfinite(value) else f'{"-":>{width}}')
    status = STATUS_LABELS[row.verdict]
    if row.reason:
        status += ': ' + ' '.join(row.reason.split())
    return ' '.join(cells) + '  ' + status + '\n'


def _workspace_text(workspace):
    """Describe a SafeWorkspace in millimetres: the cylinder, the z range and every box."""
    text = (f'radius {workspace.radius * _MM:g} mm about the base axis, z from '
            f'{workspace.z_min * _MM:g} to {workspace.z_max * _MM:g} mm')
    for index, box in enumerate(workspace.keep_out_boxes):
        text += (f', keep-out box {index} from {mm_text(box[:3]).replace(" ", "")} to '
                 f'{mm_text(box[3:]).replace(" ", "")} mm')
    return text


def _number(value, spec, scale=1.0):
    """Format ``value * scale`` with ``spec``, or '-' when it is not finite."""
    return format(value * scale, spec) if math.isfinite(value) else '-'


def format_report(report, config):
    """Return the table, the summary and the result of a run as text."""
    f = report.figures
    verdicts = [row.verdict for row in report.rows]
    limits, joints = config.limits, config.joint_limits
    lines = [
        f'pairs: {len(report.rows)} sent, {verdicts.count("ok")} executed as planned, '
        f'{verdicts.count("rejected_expected")} rejected as expected, '
        f'{verdicts.count("rejected_unexpected")} rejected unexpectedly, '
        f'{verdicts.count("invalid")} invalid published, '
        f'{verdicts.count("not_executed")} not executed as planned',
        f'planned: trajectories back to back {_number(f["planned_duration_total"], ".3f")} s '
        f'-> {_number(f["planned_picks_per_min"], ".1f")} picks/min; plan latency mean '
        f'{_number(f["plan_latency_mean"], ".1f", _MS)} ms, max '
        f'{_number(f["plan_latency_max"], ".1f", _MS)} ms; place sent to answer mean '
        f'{_number(f["round_trip_mean"], ".1f", _MS)} ms',
        f'executed (Jazzy JTC emulation at {1.0 / CONTROL_PERIOD:g} Hz): '
        f'{f["executed_cycles"]} cycles completed in {_number(f["executed_span"], ".3f")} s '
        f'-> {_number(f["executed_picks_per_min"], ".1f")} picks/min',
        'executed gap between trajectories (negative: taken up before the previous one '
        f'ended): max {_number(f["executed_gap_max"], ".1f", _MS)} ms, p50 '
        f'{_number(f["executed_gap_p50"], ".1f", _MS)} ms; '
        f'{f["executed_replacements"]} replaced while running',
        f'executed TCP vs planned paths: max deviation '
        f'{_number(f["executed_deviation_max"], ".3f", _MM)} mm (limit '
        f'{PATH_TOLERANCE * _MM:g} mm); picks and places visited in order: '
        f'{f["executed_visits"]} of {f["visit_targets"]}',
        f'executed peaks (finite differences at {1.0 / CONTROL_PERIOD:g} Hz): TCP '
        f'{_number(f["executed_peak_tcp_speed"], ".2f")} m/s (limit {limits.max_speed:g}), '
        f'{_number(f["executed_peak_tcp_accel"], ".1f")} m/s2 (limit {limits.max_accel:g}), '
        f'{_number(f["executed_peak_tcp_jerk"], ".0f")} m/s3 (limit {limits.max_jerk:g}, '
        f'{_JERK_NOTE[config.join]}); joints '
        f'{_number(f["executed_peak_joint_velocity"], ".2f")} rad/s (limit '
        f'{joints.max_velocity:g}), {_number(f["executed_peak_joint_accel"], ".1f")} rad/s2 '
        f'(limit {joints.max_acceleration:g})',
    ]
    lines.append(f"safe workspace (the node's parameters): {_workspace_text(config.workspace)}"
                 '; executed TCP ' + ('inside it throughout' if f['executed_workspace_clear']
                                      else 'NOT inside it (see the failure below)'))
    text = table_header() + ''.join(table_row(row) for row in report.rows) + '\n'
    text += ''.join(line + '\n' for line in lines)
    if report.timed_out:
        text += 'timeout: an answer or a trajectory did not come in time\n'
    text += ''.join(f'failed: {failure}\n' for failure in report.failures)
    return text + f'result: {"PASS" if report.passed else "FAIL"}\n'
