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
``ellipath demo --belt``: picks from a conveyor at 0.3 m/s, judged on the executed motion.

Objects are latched by a camera 0.15 m upstream of the tracking window, at random across
the belt and at random intervals, as a stream faster than the robot can take: some are
necessarily missed. Two engines:

* through the node (default, :func:`run_node_belt`): ``ellipath_node`` runs with the belt's
  parameters, each object is published as one ``pick_place`` message when it is latched,
  stamped with its latch time, and the node plans, reports misses and releases each pick
  stamped at its planned start, over DDS on this host; its planning time is on the robot's
  timeline, as in a cell;
* ``--belt-core``: each cycle is planned with the core alone, from where and when the
  previous one ends (no ROS, no planning latency).

Either way each trajectory is fed, stamped at its start, at its arrival time, to the emulation
of Jazzy's joint_trajectory_controller (``ellipath_ros.core.controller``, 1 kHz). The report
says, all executed (JTC's quintic through the published points, through forward kinematics):
picks/min and the miss rate, the TCP's distance to the object at each pick instant, its
speed relative to the object during the pick dwell, the peaks against the limits, and every
object's outcome (picked, or the reason the node or the core gave).
"""

from dataclasses import dataclass
import math
import os
import sys

from ellipath_ros.core.controller import executed_tcp
from ellipath_ros.core.controller import JazzyJtcEmulator
from ellipath_ros.core.conveyor import Conveyor
from ellipath_ros.core.conveyor import next_belt_pick
from ellipath_ros.core.conveyor import PICK_ORDERS
from ellipath_ros.core.joint_trajectory import EXECUTED_KEYS
from ellipath_ros.core.joint_trajectory import executed_peaks
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.planner import executed_bounds
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.sequencing import final_rest
import numpy as np

BELT_Z = -0.85
CAMERA_X = -0.45  # m, where objects are latched (upstream of the window)
ACROSS = (-0.15, 0.15)  # m, y range of the objects
WINDOW = (-0.3, 0.25)  # m, tracking window along the belt (x)
PLACES = tuple((0.16, y, -0.80) for y in (-0.1, 0.0, 0.1))
HOME = (0.0, 0.0, -0.8)
DWELL = 0.035  # s, gripper close and open
# Each trajectory reaches the controller this long before its stamp: inside the previous
# one's place dwell, so that it never replaces a moving trajectory.
HANDOVER = 0.02  # s
# Executed requirements: TCP on the object at the pick, and relative speed while gripping.
ON_OBJECT = 1e-4  # m
RELATIVE_SPEED = 1e-3  # m/s
# Dwell samples for the relative speed, and their central-difference step [s].
DWELL_SAMPLES = 36
SPEED_STEP = 1e-5
# Time step of the figure's curves [s].
FIGURE_STEP = 1e-3
# Through the node: the first object is latched this long after the node and the cell have
# met [s]; after the last trajectory's predicted end, strays have this long to show up [s].
LEAD_IN = 0.5
SETTLE = 0.2


def add_belt_arguments(parser):
    """Add the belt scenario's options to the ``ellipath demo`` parser."""
    parser.add_argument('--belt', action='store_true',
                        help='the belt scenario instead of the static one: objects on a '
                        'conveyor at --belt-speed, sent to the node as they are latched, '
                        'executed on the JTC emulation')
    parser.add_argument('--belt-core', action='store_true',
                        help='with --belt: plan with the core alone (no ROS, no planning '
                        'latency), as the robot timeline would be with instant plans')
    parser.add_argument('--order', choices=PICK_ORDERS, default='latch',
                        help='with --belt-core: which waiting object is taken when the robot '
                        'is free: the first in latch order that can still be caught, or the '
                        'one whose cycle ends soonest unless that loses the first (default: '
                        '%(default)s, as the node, which takes its belt pairs in latch order)')
    parser.add_argument('--belt-speed', type=float, default=0.3,
                        help='belt speed along +x [m/s] (default: %(default)s)')
    parser.add_argument('--place-belt', type=float, nargs=3, default=(0.0, 0.0, 0.0),
                        metavar=('VX', 'VY', 'VZ'),
                        help='with --belt: place belt (tray) velocity [m/s], at any angle to '
                        'the pick belt, e.g. 0 0.3 0 (default: still places)')
    parser.add_argument('--objects', type=int, default=20,
                        help='objects latched, belt scenario (default: %(default)s)')
    parser.add_argument('--rate', type=float, default=2.5,
                        help='mean objects per second on the belt (default: %(default)s)')
    parser.add_argument('--seed', type=int, default=12, help='random stream (default: 12)')


def object_stream(count, rate, seed):
    """Return latch times (N,) [s] and positions (N, 3) [m] of a random stream."""
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.exponential(1.0 / rate, count))
    across = rng.uniform(*ACROSS, count)
    positions = np.column_stack((np.full(count, CAMERA_X), across, np.full(count, BELT_Z)))
    return times, positions


@dataclass(frozen=True, eq=False)
class BeltPick:
    """
    One executed belt pick: the trajectory that picks an object, as the controller got it.

    Times are on one clock [s]: the latch clock of the objects.
    """

    number: int  # the object's index in the stream
    latch_time: float
    latched: np.ndarray  # object position at latch_time [m], (3,)
    start: float  # header.stamp: the trajectory's t = 0
    arrival: float  # when the controller had the message
    trajectory: JointTrajectoryData
    pick_after_start: float  # planned pick instant, from the start
    window_position: float  # [m] along the belt at the pick (planned)
    wait: float  # [s] rest at the start before the approach (planned)
    place: np.ndarray  # where the TCP places [m], (3,)
    place_after_start: float  # planned place instant, from the start


def run_belt_scenario(count=20, speed=0.3, rate=2.5, seed=12, config=None, order='latch',
                      place_velocity=(0.0, 0.0, 0.0)):
    """
    Play the belt cell with the core alone; return a JSON-ready dict of what was executed.

    Whenever the robot is free, the objects latched by then wait, and ``order`` says which is
    taken (:func:`~ellipath_ros.core.conveyor.next_belt_pick`); the others wait for the next
    cycle or, missed, are reported at once. Every figure is of the executed motion unless its
    key says ``planned``. ``place_velocity``: the place belt's [m/s], (3,).
    """
    config = config or PlannerConfig()
    conveyor = Conveyor(velocity=np.array([speed, 0.0, 0.0]), place_velocity=place_velocity,
                        window_upstream=WINDOW[0], window_downstream=WINDOW[1])
    latches, objects = object_stream(count, rate, seed)
    position, free_at = np.array(HOME), 0.0
    picks, misses = [], []
    waiting = list(range(count))
    while waiting:
        start = max(free_at, latches[waiting[0]])
        candidates = [(number, latches[number], objects[number]) for number in waiting
                      if latches[number] <= start]
        place = np.array(PLACES[len(picks) % len(PLACES)])
        (number, plan), rejected = next_belt_pick(
            position, start, candidates, place, config, conveyor, pick_dwell=DWELL,
            place_dwell=DWELL, order=order)
        for missed, error in rejected.items():
            misses.append({'object': missed, 'kind': error.kind, 'reason': str(error)})
            waiting.remove(missed)
        if number is None:
            continue
        waiting.remove(number)
        trajectory = plan.joint_trajectory
        # Delivered before its stamp, inside the previous place dwell (or while idle): the
        # controller holds the robot at rest until the stamp, so it starts exactly then.
        arrival = max(start - HANDOVER, picks[-1].arrival if picks else 0.0)
        picks.append(BeltPick(number, latches[number], objects[number], start, arrival,
                              trajectory, plan.intercept.pick_time - start,
                              plan.intercept.window_position, plan.intercept.wait, place,
                              plan.metrics['belt.place_after_start']))
        # The next one is handed over HANDOVER before its stamp, which must be while this one
        # rests at its end (a moving place ends with its exit, not at rest: then later).
        position = plan.end_position
        free_at = start + trajectory.duration + max(0.0, HANDOVER - final_rest(trajectory))
    result = evaluate_belt_run(picks, misses, count, speed, config, HOME, place_velocity)
    result.update(rate_per_s=rate, engine='core', order=order)
    return result


def evaluate_belt_run(picks, misses, count, speed, config, home,
                      place_velocity=(0.0, 0.0, 0.0)):
    """
    Replay belt picks on the JTC emulation; return a JSON-ready dict of what was executed.

    Parameters
    ----------
    picks : list of BeltPick
        In the order the controller received them.
    misses : list of dict
        ``{'object', 'kind', 'reason'}`` of every object not picked.
    count : int
        Objects in the stream.
    speed : float
        Belt speed along +x [m/s].
    config : PlannerConfig
        The planner's settings (geometry, limits, joint names).
    home : array_like
        Where the robot rests before the first trajectory [m], (3,).
    place_velocity : array_like
        The place belt's velocity [m/s], (3,): the TCP rides on it in the place dwell.

    """
    velocity = np.array([speed, 0.0, 0.0])
    place_velocity = np.asarray(place_velocity, dtype=float)
    first = picks[0].arrival - 1.0 if picks else 0.0
    emulator = JazzyJtcEmulator(config.joint_names, start_time=first,
                                initial_positions=inverse_kinematics(np.asarray(home, float),
                                                                     config.geometry))
    worst = dict.fromkeys(('on_object', 'relative_speed', 'on_place', 'place_relative_speed'),
                          0.0)
    peaks = dict.fromkeys(('peak_speed', 'peak_accel', 'peak_jerk', 'joint_peak_velocity',
                           'joint_peak_accel'), 0.0)
    rows = []
    for pick in picks:
        trajectory = pick.trajectory
        emulator.receive(trajectory, pick.start, pick.arrival)
        dwell = pick.pick_after_start + np.linspace(0.0, DWELL, DWELL_SAMPLES)
        tcp = forward_kinematics(quintic_interpolate(trajectory, dwell)[0], config.geometry)
        object_path = pick.latched + np.outer(dwell + pick.start - pick.latch_time, velocity)
        ahead = forward_kinematics(quintic_interpolate(trajectory, dwell[1:-1] + SPEED_STEP)[0],
                                   config.geometry)
        behind = forward_kinematics(
            quintic_interpolate(trajectory, dwell[1:-1] - SPEED_STEP)[0], config.geometry)
        relative = (ahead - behind) / (2.0 * SPEED_STEP) - velocity
        at_pick = float(np.linalg.norm(tcp[0] - object_path[0]))
        worst['on_object'] = max(worst['on_object'],
                                 float(np.linalg.norm(tcp - object_path, axis=1).max()))
        worst['relative_speed'] = max(worst['relative_speed'],
                                      float(np.linalg.norm(relative, axis=1).max()))
        on_place, place_speed = _placed(pick, place_velocity, config)
        worst['on_place'] = max(worst['on_place'], on_place)
        worst['place_relative_speed'] = max(worst['place_relative_speed'], place_speed)
        for key, value in executed_peaks(trajectory, config.geometry).items():
            peaks[key] = max(peaks[key], value)
        rows.append({'object': pick.number,
                     'pick_after_latch': pick.start + pick.pick_after_start - pick.latch_time,
                     'window_position': pick.window_position, 'wait': pick.wait,
                     'start': pick.start, 'duration': trajectory.duration,
                     'executed.tcp_to_object_at_pick': at_pick})
    deviation, timeline = 0.0, None
    if picks:
        emulator.run_until(picks[-1].start + picks[-1].trajectory.duration + 0.01)
        samples = emulator.samples()
        timeline = executed_tcp(samples, config.geometry)
        # Each row the emulated controller commanded, against the trajectory that commanded
        # it at that time: the timeline runs the plans exactly, none cut short or started late.
        for index, pick in enumerate(picks):
            rows_of = samples.source == index
            local = np.clip(samples.times[rows_of] - pick.start, 0.0, pick.trajectory.duration)
            planned = forward_kinematics(quintic_interpolate(pick.trajectory, local)[0],
                                         config.geometry)
            deviation = max(deviation, float(np.linalg.norm(
                timeline.positions[rows_of] - planned, axis=1).max(initial=0.0)))
    span = (picks[-1].start + picks[-1].trajectory.duration - picks[0].start) if picks else 0.0
    limits, joints = config.limits, config.joint_limits
    outcomes = sorted([{'object': row['object'], 'outcome': 'picked'} for row in rows]
                      + [{'object': miss['object'], 'outcome': miss['kind'],
                          'reason': miss['reason']} for miss in misses],
                      key=lambda outcome: outcome['object'])
    return {
        'objects': count, 'belt_speed': speed, 'picked': len(picks),
        'missed': len(misses), 'miss_rate': len(misses) / count,
        'executed.picks_per_min': 60.0 * len(picks) / span if span > 0.0 else 0.0,
        'executed.max_tcp_to_object_at_pick': worst['on_object'],
        'executed.max_relative_speed_in_dwell': worst['relative_speed'],
        'place_belt_velocity': place_velocity.tolist(),
        'executed.max_tcp_to_place': worst['on_place'],
        'executed.max_relative_speed_in_place_dwell': worst['place_relative_speed'],
        **{f'executed.{key}': value for key, value in peaks.items()},
        'executed.emulated_deviation_from_plans': deviation,
        'executed.emulated_1khz_peak_speed': timeline.peak_speed if timeline else 0.0,
        'executed.emulated_1khz_peak_accel': timeline.peak_acceleration if timeline else 0.0,
        'limits': {'max_speed': limits.max_speed, 'max_accel': limits.max_accel,
                   'max_jerk': limits.max_jerk, 'max_joint_velocity': joints.max_velocity,
                   'max_joint_accel': joints.max_acceleration,
                   # What the planner allows the executed jerk (1.1 x max_jerk with g2 joins).
                   'executed_jerk_bound': float(dict(zip(EXECUTED_KEYS, executed_bounds(
                       config)))['peak_jerk'])},
        'picks': rows, 'misses': misses, 'outcomes': outcomes,
    }


def _placed(pick, place_velocity, config):
    """
    Return the executed TCP's distance to the place and its speed relative to the place belt.

    The distance at the place instant, the largest relative speed during the place dwell.
    """
    dwell = pick.place_after_start + np.linspace(0.0, DWELL, DWELL_SAMPLES)
    trajectory = pick.trajectory
    tcp = forward_kinematics(quintic_interpolate(trajectory, dwell[:1])[0], config.geometry)
    ahead, behind = (forward_kinematics(quintic_interpolate(trajectory, dwell[1:-1] + step)[0],
                                        config.geometry) for step in (SPEED_STEP, -SPEED_STEP))
    relative = (ahead - behind) / (2.0 * SPEED_STEP) - place_velocity
    return (float(np.linalg.norm(tcp[0] - pick.place)),
            float(np.linalg.norm(relative, axis=1).max()))


def failures(result):
    """Return the failed checks of a belt run, as lines."""
    limits = result['limits']
    checks = [
        (result['executed.max_tcp_to_object_at_pick'] <= ON_OBJECT,
         f'TCP on the object within {ON_OBJECT * 1e3:g} mm at every pick'),
        (result['executed.max_relative_speed_in_dwell'] <= RELATIVE_SPEED,
         f'relative speed within {RELATIVE_SPEED * 1e3:g} mm/s during every dwell'),
        (result['executed.max_tcp_to_place'] <= ON_OBJECT,
         f'TCP on the place within {ON_OBJECT * 1e3:g} mm at every place'),
        (result['executed.max_relative_speed_in_place_dwell'] <= RELATIVE_SPEED,
         f'speed relative to the place belt within {RELATIVE_SPEED * 1e3:g} mm/s during every '
         'place dwell'),
        (result['executed.peak_speed'] <= limits['max_speed'], 'TCP speed limit'),
        (result['executed.peak_accel'] <= limits['max_accel'], 'TCP acceleration limit'),
        (result['executed.peak_jerk'] <= limits['executed_jerk_bound'],
         f"TCP jerk within {limits['executed_jerk_bound']:g} m/s^3"),
        (result['executed.joint_peak_velocity'] <= limits['max_joint_velocity'],
         'joint speed limit'),
        (result['executed.joint_peak_accel'] <= limits['max_joint_accel'],
         'joint acceleration limit'),
        (all(miss['kind'] == 'missed' for miss in result['misses']),
         'every object not picked rejected as missed'),
        (result['picked'] > 0, 'at least one pick'),
        (result['executed.emulated_deviation_from_plans'] <= ON_OBJECT,
         f'emulated controller within {ON_OBJECT * 1e3:g} mm of every trajectory it ran'),
        (len(result['outcomes']) == result['objects'], 'an outcome for every object'),
        (result.get('trajectories_received', result['picked']) == result['picked'],
         'one trajectory received for every pick released'),
    ]
    return [text for passed, text in checks if not passed]


def format_belt_report(result):
    """Return the human-readable report of a belt run."""
    how = ('through ellipath_node over DDS (its belt release, stamped ahead; pairs in '
           'latch order)' if result['engine'] == 'node' else
           f"planned with the core alone (no ROS), order {result['order']}")
    lines = [
        f"ellipath demo --belt: {result['objects']} objects at {result['rate_per_s']:g}/s on a "
        f"belt at {result['belt_speed']:g} m/s, window x in [{WINDOW[0]:g}, {WINDOW[1]:g}] m, "
        f'{how}',
        f"picked {result['picked']}, missed {result['missed']} "
        f"({100.0 * result['miss_rate']:.0f} %), "
        f"{result['executed.picks_per_min']:.1f} picks/min executed (from the first stamp to "
        'the last end, as the emulated controller ran them)',
        'executed TCP to object at the pick: max '
        f"{result['executed.max_tcp_to_object_at_pick'] * 1e3:.3g} mm; relative speed in the "
        f"dwell: max {result['executed.max_relative_speed_in_dwell'] * 1e3:.3g} mm/s; emulated "
        'controller (1 kHz) off the trajectories it ran: max '
        f"{result['executed.emulated_deviation_from_plans'] * 1e3:.3g} mm",
        f"place belt {result['place_belt_velocity']} m/s: executed TCP to place at the place: "
        f"max {result['executed.max_tcp_to_place'] * 1e3:.3g} mm; speed relative to the place "
        'belt in the place dwell: max '
        f"{result['executed.max_relative_speed_in_place_dwell'] * 1e3:.3g} mm/s",
        f"executed peaks: {result['executed.peak_speed']:.4g} m/s, "
        f"{result['executed.peak_accel']:.4g} m/s^2, {result['executed.peak_jerk']:.5g} m/s^3; "
        f"joints {result['executed.joint_peak_velocity']:.4g} rad/s, "
        f"{result['executed.joint_peak_accel']:.4g} rad/s^2 (limits "
        + ', '.join(f'{key} {value:g}' for key, value in result['limits'].items()) + ')',
    ]
    if result['engine'] == 'node':
        lines.append(f"the node's belt plans (wall time, this machine): median "
                     f"{result['node_plan_time_p50'] * 1e3:.0f} ms, max "
                     f"{result['node_plan_time_max'] * 1e3:.0f} ms; each pick starts that "
                     'much later, twice that ahead while the robot is idle')
    picked = {row['object']: row for row in result['picks']}
    for outcome in result['outcomes']:
        number = outcome['object']
        if number in picked:
            row = picked[number]
            lines.append(
                f"object {number}: picked {row['pick_after_latch']:.3f} s after its latch at "
                f"x = {row['window_position']:.3f} m (planned), executed TCP to object "
                f"{row['executed.tcp_to_object_at_pick'] * 1e3:.2g} mm")
        else:
            lines.append(f"object {number}: {outcome['outcome']}: {outcome['reason']}")
    lines += [f'failed: {text}' for text in failures(result)]
    return '\n'.join(lines) + '\n'


def write_belt_figure(plan, pick, velocity, latch_time, out_dir):
    """
    Draw one belt cycle as executed, in the base frame and in the belt frame; return the path.

    Horizontal axis: the TCP along the belt direction, in the base frame and less the belt's
    travel since the latch (there the object stands still: the descent and the lift are
    vertical lines onto it). Needs matplotlib (the ``plot`` extra).
    """
    from ellipath_ros.paper.plotting import _new_figure, _save
    trajectory = plan.joint_trajectory
    t = np.arange(0.0, trajectory.duration, FIGURE_STEP)
    tcp = forward_kinematics(quintic_interpolate(trajectory, t)[0], PlannerConfig().geometry)
    direction = velocity / np.linalg.norm(velocity)
    along = tcp @ direction
    travel = np.linalg.norm(velocity) * (plan.start_time + t - latch_time)
    object_along = float(np.dot(pick, direction))
    figure, axes = _new_figure(1, 2, size=(10.0, 4.0))
    for axis, horizontal, title in ((axes[0, 0], along, 'base frame'),
                                    (axes[0, 1], along - travel, 'belt frame (object fixed)')):
        axis.plot(horizontal, tcp[:, 2], color='tab:blue', label='executed TCP')
        axis.set_title(title)
        axis.set_xlabel('along the belt [m]')
        axis.set_ylabel('z [m]')
        axis.set_aspect('equal', adjustable='datalim')
    pick_time = plan.intercept.pick_time
    axes[0, 0].plot([object_along, object_along + np.linalg.norm(velocity) * (
        pick_time - latch_time)], [pick[2]] * 2, color='tab:orange', label='object')
    axes[0, 1].plot([object_along], [pick[2]], 'o', color='tab:orange', label='object')
    axes[0, 0].legend()
    os.makedirs(out_dir, exist_ok=True)
    return _save(figure, out_dir, 'belt_cycle.png')


def belt_options_error(args):
    """Return what is wrong with the belt scenario's options, or None."""
    place_speed = float(np.linalg.norm(args.place_belt))
    if args.objects < 1 or not (0.0 < args.belt_speed <= 1.0) or not math.isfinite(args.rate) \
            or args.rate <= 0.0 or not place_speed <= 1.0:
        return ('expected --objects >= 1, --belt-speed in (0, 1] m/s, --rate > 0 and a '
                '--place-belt speed of at most 1 m/s')
    return None


def run_belt_demo(args):
    """Run the belt scenario with the core alone; return the exit status (0, 1 or 2)."""
    error = belt_options_error(args)
    if error is not None:
        sys.stderr.write(f'ellipath demo --belt: {error}\n')
        return 2
    result = run_belt_scenario(args.objects, args.belt_speed, args.rate, args.seed,
                               order=args.order, place_velocity=args.place_belt)
    sys.stdout.write(format_belt_report(result))
    return 1 if failures(result) else 0


def belt_parameters(speed, place_velocity=(0.0, 0.0, 0.0)):
    """Return the node parameters of the belt cell, as (name, value) pairs."""
    return [('conveyor_velocity', [float(speed), 0.0, 0.0]),
            ('place_conveyor_velocity', [float(value) for value in place_velocity]),
            ('tracking_window_upstream', WINDOW[0]), ('tracking_window_downstream', WINDOW[1]),
            ('pick_dwell', DWELL), ('place_dwell', DWELL), ('home_position', list(HOME))]


def run_node_belt(args, cell, timeout):
    """
    Play the belt cell through the node; return (result dict or None, whether it timed out).

    Each object goes out as one ``pick_place`` message when the camera latches it (at its
    time in the stream, on the node clock), stamped with that time. The node plans it from the
    end of its queue (or, idle, a stamp ahead), reports a miss with its reason, and releases
    each pick stamped at its planned start. Every object's outcome is the node's last word
    on its pair: ``released`` (picked) or an ERROR status with its kind and reason. The
    trajectories are then replayed at their arrival times on the JTC emulation.
    """
    # ROS message conversions are imported here: the core scenario runs without ROS.
    from ellipath_ros.conversions import joint_trajectory_data

    latches, objects = object_stream(args.objects, args.rate, args.seed)
    origin = cell.now_ns() + int(LEAD_IN * 1e9)
    stamps = [origin + int(round(latch * 1e9)) for latch in latches]
    for number, (stamp, pick) in enumerate(zip(stamps, objects)):
        cell.spin_until(lambda stamp=stamp: cell.now_ns() >= stamp, timeout + LEAD_IN)
        cell.send_pick_place(pick, PLACES[number % len(PLACES)], stamp)
    # Pair numbers count from 1 in the order the node took the messages: the stream's.
    if not cell.spin_until(lambda: len(_final_answers(cell.statuses())) >= args.objects,
                           timeout + latches[-1]):
        return None, True
    answers = _final_answers(cell.statuses())
    released = [values for message, values in answers.values() if message == 'released']
    if not cell.wait_for_trajectories(len(released), timeout, SETTLE):
        return None, True
    # The k-th trajectory is the k-th released pair's (the node publishes, then reports).
    released = sorted(released, key=lambda values: int(values['release_order']))
    picks, misses = [], []
    for (message, arrival), values in zip(cell.received_messages(), released):
        number = int(values['pair']) - 1
        start_ns = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
        picks.append(BeltPick(
            number, (stamps[number] - origin) * 1e-9, objects[number],
            (start_ns - origin) * 1e-9, arrival - origin * 1e-9,
            joint_trajectory_data(message), float(values['belt.pick_after_start']),
            float(values['belt.window_position']), float(values['belt.wait']),
            np.array(PLACES[number % len(PLACES)]), float(values['belt.place_after_start'])))
    for pair, (message, values) in sorted(answers.items()):
        if message != 'released':
            misses.append({'object': pair - 1, 'kind': values.get('kind', 'unknown'),
                           'reason': message})
    result = evaluate_belt_run(picks, misses, args.objects, args.belt_speed, cell.config, HOME,
                               args.place_belt)
    plan_times = [float(values['plan_time']) for level, message, values in cell.statuses()
                  if message == 'planned' and 'plan_time' in values]
    result.update(rate_per_s=args.rate, engine='node',
                  trajectories_received=len(cell.received_messages()),
                  node_plan_time_p50=float(np.median(plan_times)) if plan_times else 0.0,
                  node_plan_time_max=max(plan_times, default=0.0))
    return result, False


def _final_answers(statuses):
    """Return {pair: (message, values)}: each pair's release, or the ERROR that ended it."""
    answers = {}
    for order, (level, message, values) in enumerate(statuses):
        if 'pair' not in values:
            continue
        if level == 'OK' and message == 'released':
            answers[int(values['pair'])] = (message, {**values, 'release_order': order})
        elif level == 'ERROR':
            answers[int(values['pair'])] = (message, values)
    return answers
