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
necessarily missed. Each cycle is planned with the core (no ROS: the robot's timeline, not
this machine's planning time, is what is measured) from where and when the previous one
ends, and each trajectory is fed, stamped at its planned start, to the emulation of Jazzy's
joint_trajectory_controller (``ellipath_ros.core.controller``, 1 kHz). The report says, all
executed (JTC's quintic through the published points, through forward kinematics):
picks/min and the miss rate, the TCP's distance to the object at each pick instant, its
speed relative to the object during the pick dwell, and the peaks against the limits.
"""

import math
import os
import sys

from ellipath_ros.core.controller import executed_tcp
from ellipath_ros.core.controller import JazzyJtcEmulator
from ellipath_ros.core.conveyor import Conveyor
from ellipath_ros.core.conveyor import plan_belt_cycle
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import executed_peaks
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.planner import PlannerConfig
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


def add_belt_arguments(parser):
    """Add the belt scenario's options to the ``ellipath demo`` parser."""
    parser.add_argument('--belt', action='store_true',
                        help='the belt scenario instead of the node demo: objects on a conveyor '
                        'at --belt-speed, planned with the core and executed on the JTC '
                        'emulation (no ROS)')
    parser.add_argument('--belt-speed', type=float, default=0.3,
                        help='belt speed along +x [m/s] (default: %(default)s)')
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


def run_belt_scenario(count=20, speed=0.3, rate=2.5, seed=12, config=None):
    """
    Play the belt cell; return a JSON-ready dict of what was executed.

    Every figure is of the executed motion unless its key says ``planned``.
    """
    config = config or PlannerConfig()
    conveyor = Conveyor(velocity=np.array([speed, 0.0, 0.0]), window_upstream=WINDOW[0],
                        window_downstream=WINDOW[1])
    velocity = conveyor.velocity
    latches, objects = object_stream(count, rate, seed)
    position, free_at = np.array(HOME), 0.0
    emulator = JazzyJtcEmulator(config.joint_names, start_time=0.0,
                                initial_positions=inverse_kinematics(position, config.geometry))
    picks, misses, sent = [], [], []
    worst = {'on_object': 0.0, 'relative_speed': 0.0}
    peaks = dict.fromkeys(('peak_speed', 'peak_accel', 'peak_jerk', 'joint_peak_velocity',
                           'joint_peak_accel'), 0.0)
    for number, (latch, pick) in enumerate(zip(latches, objects)):
        start = max(free_at, latch)
        place = np.array(PLACES[len(picks) % len(PLACES)])
        try:
            plan = plan_belt_cycle(position, pick, place, config, conveyor, pick_dwell=DWELL,
                                   place_dwell=DWELL, latch_time=latch, start_time=start)
        except EllipathError as error:
            misses.append({'object': number, 'kind': error.kind, 'reason': str(error)})
            continue
        trajectory = plan.joint_trajectory
        # Delivered before its stamp, inside the previous place dwell (or while idle): the
        # controller holds the robot at rest until the stamp, so it starts exactly then.
        emulator.receive(trajectory, start, max(start - HANDOVER, emulator.time))
        sent.append((start, trajectory))
        offset = plan.intercept.pick_time - start
        dwell = offset + np.linspace(0.0, DWELL, DWELL_SAMPLES)
        tcp = forward_kinematics(quintic_interpolate(trajectory, dwell)[0], config.geometry)
        object_path = pick + np.outer(dwell + start - latch, velocity)
        ahead = forward_kinematics(quintic_interpolate(trajectory, dwell[1:-1] + SPEED_STEP)[0],
                                   config.geometry)
        behind = forward_kinematics(
            quintic_interpolate(trajectory, dwell[1:-1] - SPEED_STEP)[0], config.geometry)
        relative = (ahead - behind) / (2.0 * SPEED_STEP) - velocity
        worst['on_object'] = max(worst['on_object'],
                                 float(np.linalg.norm(tcp - object_path, axis=1).max()))
        worst['relative_speed'] = max(worst['relative_speed'],
                                      float(np.linalg.norm(relative, axis=1).max()))
        for key, value in executed_peaks(trajectory, config.geometry).items():
            peaks[key] = max(peaks[key], value)
        picks.append({'object': number, 'pick_after_latch': plan.intercept.pick_time - latch,
                      'window_position': plan.intercept.window_position,
                      'wait': plan.intercept.wait, 'start': start,
                      'duration': trajectory.duration})
        position, free_at = plan.end_position, start + trajectory.duration
    emulator.run_until(free_at + 0.01)
    samples = emulator.samples()
    timeline = executed_tcp(samples, config.geometry)
    # Each row the emulated controller commanded, against the trajectory that commanded it
    # at that time: the timeline runs the plans exactly, none cut short or started late.
    deviation = 0.0
    for index, (plan_start, trajectory) in enumerate(sent):
        rows = samples.source == index
        local = np.clip(samples.times[rows] - plan_start, 0.0, trajectory.duration)
        planned = forward_kinematics(quintic_interpolate(trajectory, local)[0], config.geometry)
        deviation = max(deviation, float(np.linalg.norm(
            timeline.positions[rows] - planned, axis=1).max(initial=0.0)))
    span = (picks[-1]['start'] + picks[-1]['duration'] - picks[0]['start']) if picks else 0.0
    limits, joints = config.limits, config.joint_limits
    return {
        'objects': count, 'belt_speed': speed, 'rate_per_s': rate, 'picked': len(picks),
        'missed': len(misses), 'miss_rate': len(misses) / count,
        'executed.picks_per_min': 60.0 * len(picks) / span if span > 0.0 else 0.0,
        'executed.max_tcp_to_object_at_pick': worst['on_object'],
        'executed.max_relative_speed_in_dwell': worst['relative_speed'],
        **{f'executed.{key}': value for key, value in peaks.items()},
        'executed.emulated_deviation_from_plans': deviation,
        'executed.emulated_1khz_peak_speed': timeline.peak_speed,
        'executed.emulated_1khz_peak_accel': timeline.peak_acceleration,
        'limits': {'max_speed': limits.max_speed, 'max_accel': limits.max_accel,
                   'max_jerk': limits.max_jerk, 'max_joint_velocity': joints.max_velocity,
                   'max_joint_accel': joints.max_acceleration},
        'picks': picks, 'misses': misses,
    }


def failures(result):
    """Return the failed checks of a belt run, as lines."""
    limits = result['limits']
    checks = [
        (result['executed.max_tcp_to_object_at_pick'] <= ON_OBJECT,
         f'TCP on the object within {ON_OBJECT * 1e3:g} mm at every pick'),
        (result['executed.max_relative_speed_in_dwell'] <= RELATIVE_SPEED,
         f'relative speed within {RELATIVE_SPEED * 1e3:g} mm/s during every dwell'),
        (result['executed.peak_speed'] <= limits['max_speed'], 'TCP speed limit'),
        (result['executed.peak_accel'] <= limits['max_accel'], 'TCP acceleration limit'),
        (result['executed.joint_peak_velocity'] <= limits['max_joint_velocity'],
         'joint speed limit'),
        (result['executed.joint_peak_accel'] <= limits['max_joint_accel'],
         'joint acceleration limit'),
        (all(miss['kind'] == 'missed' for miss in result['misses']),
         'every object not picked rejected as missed'),
        (result['picked'] > 0, 'at least one pick'),
        (result['executed.emulated_deviation_from_plans'] <= ON_OBJECT,
         f'emulated controller within {ON_OBJECT * 1e3:g} mm of every trajectory it ran'),
    ]
    return [text for passed, text in checks if not passed]


def format_belt_report(result):
    """Return the human-readable report of a belt run."""
    lines = [
        f"ellipath demo --belt: {result['objects']} objects at {result['rate_per_s']:g}/s on a "
        f"belt at {result['belt_speed']:g} m/s, window x in [{WINDOW[0]:g}, {WINDOW[1]:g}] m",
        f"picked {result['picked']}, missed {result['missed']} "
        f"({100.0 * result['miss_rate']:.0f} %), "
        f"{result['executed.picks_per_min']:.1f} picks/min executed (from the first stamp to "
        'the last end, as the emulated controller ran them)',
        'executed TCP to object at the pick: max '
        f"{result['executed.max_tcp_to_object_at_pick'] * 1e3:.3g} mm; relative speed in the "
        f"dwell: max {result['executed.max_relative_speed_in_dwell'] * 1e3:.3g} mm/s; emulated "
        'controller (1 kHz) off the trajectories it ran: max '
        f"{result['executed.emulated_deviation_from_plans'] * 1e3:.3g} mm",
        f"executed peaks: {result['executed.peak_speed']:.4g} m/s, "
        f"{result['executed.peak_accel']:.4g} m/s^2, {result['executed.peak_jerk']:.5g} m/s^3; "
        f"joints {result['executed.joint_peak_velocity']:.4g} rad/s, "
        f"{result['executed.joint_peak_accel']:.4g} rad/s^2 (limits "
        + ', '.join(f'{key} {value:g}' for key, value in result['limits'].items()) + ')',
    ]
    lines += [f"missed object {miss['object']}: {miss['reason']}" for miss in result['misses']]
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


def run_belt_demo(args):
    """Run the belt scenario from the demo's options; return the exit status (0 or 1)."""
    if args.objects < 1 or not (0.0 < args.belt_speed <= 1.0) or not math.isfinite(args.rate) \
            or args.rate <= 0.0:
        sys.stderr.write('ellipath demo --belt: expected --objects >= 1, --belt-speed in '
                         '(0, 1] m/s and --rate > 0\n')
        return 2
    result = run_belt_scenario(args.objects, args.belt_speed, args.rate, args.seed)
    sys.stdout.write(format_belt_report(result))
    return 1 if failures(result) else 0
