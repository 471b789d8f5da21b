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
The ``ellipath`` command: plan, bench, demo and plot, with the node's defaults.

``ellipath plan`` calls the core directly (no ROS needed); ``demo`` starts
the ROS 2 node; ``plot`` needs the ``plot`` extra and ``bench`` the ``bench``
extra. Exit status 2 means a rejected input or malformed arguments (the
reason on stderr, or a JSON ``error`` object on stdout with ``--json``).
"""

import argparse
import json
import math
import sys

from ellipath_ros.belt_demo import write_belt_figure
from ellipath_ros.core.conveyor import Conveyor, plan_belt_cycle
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.planner import plan_transfer, PlannerConfig
from ellipath_ros.core.settings import SETTINGS
import numpy as np

# Options of ``plan`` and ``plot``: every row of the settings table that names one.
_PLAN_SETTINGS = tuple(setting for setting in SETTINGS if setting.cli)
_OPTION_TYPES = {'double': float, 'integer': int, 'string': str}


class _ArgumentsRejected(Exception):
    """Malformed command-line arguments, raised instead of argparse's exit."""

    def __init__(self, parser, message):
        super().__init__(message)
        self.parser = parser


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser (and subparsers) that lets ``main`` report its errors as JSON."""

    def error(self, message):
        raise _ArgumentsRejected(self, message)


def _add_plan_arguments(parser):
    parser.add_argument('--pick', nargs=3, type=float, required=True, metavar=('X', 'Y', 'Z'),
                        help='pick point P1 in the base frame [m]')
    parser.add_argument('--place', nargs=3, type=float, required=True, metavar=('X', 'Y', 'Z'),
                        help='place point P2 in the base frame [m]')
    for setting in _PLAN_SETTINGS:
        unit = f' [{setting.unit}]' if setting.unit else ''
        allowed = f', {setting.allowed}' if setting.allowed else ''
        # argparse formats help with %: a literal one must be doubled.
        text = f'{setting.description}{unit}{allowed}'.replace('%', '%%')
        if setting.kind == 'double_array':
            parser.add_argument(setting.cli, dest=setting.name, nargs='*', type=float,
                                default=list(setting.default), metavar='V',
                                help=f'{text} (default: {list(setting.default) or "none"})')
        else:
            metavar = '{' + ','.join(setting.choices) + '}' if setting.choices else 'X'
            parser.add_argument(setting.cli, dest=setting.name, metavar=metavar,
                                type=_OPTION_TYPES[setting.kind], default=setting.default,
                                help=f'{text} (default: %(default)s)')
    parser.add_argument('--json', action='store_true', help='print one JSON object')


def _config_from(args):
    """Build the planner config from the parsed options (validated by the core)."""
    return PlannerConfig.from_flat({setting.name: getattr(args, setting.name)
                                    for setting in _PLAN_SETTINGS})


# -- conveyor tracking (issue 12): a pick from a moving belt plans the whole cycle ----------
def _add_belt_arguments(parser):
    defaults = Conveyor()
    parser.add_argument('--conveyor-velocity', nargs=3, type=float, default=[0.0, 0.0, 0.0],
                        metavar=('VX', 'VY', 'VZ'), help='pick belt velocity in the base '
                        'frame [m/s]; nonzero plans the whole cycle from --start, the TCP '
                        'moving with the object from the descent to the lift (default: still)')
    parser.add_argument('--pick-time', type=float, default=0.0, metavar='T',
                        help='time at which the object was at --pick, the cycle starting at 0 '
                        '[s] (default: %(default)s)')
    parser.add_argument('--place-conveyor-velocity', nargs=3, type=float,
                        default=[0.0, 0.0, 0.0], metavar=('VX', 'VY', 'VZ'),
                        help='place belt (tray) velocity [m/s] (default: still)')
    parser.add_argument('--tracking-window', nargs=2, type=float,
                        default=[defaults.window_upstream, defaults.window_downstream],
                        metavar=('UPSTREAM', 'DOWNSTREAM'), help='where picks may happen, '
                        'along the belt direction [m] (default: %(default)s)')
    parser.add_argument('--start', nargs=3, type=float, default=[0.0, 0.0, -0.8],
                        metavar=('X', 'Y', 'Z'), help='TCP at rest at the cycle start, belt '
                        'picks only [m] (default: %(default)s)')
    parser.add_argument('--pick-dwell', type=float, default=0.0,
                        help='dwell on the object, moving with it, belt picks only [s] '
                        '(default: %(default)s)')


def _conveyor_from(args):
    return Conveyor(velocity=args.conveyor_velocity,
                    place_velocity=args.place_conveyor_velocity,
                    window_upstream=args.tracking_window[0],
                    window_downstream=args.tracking_window[1])


def _belt_result(args, config):
    """Plan a belt cycle; return its JSON-ready result dict, or None on still belts."""
    conveyor = _conveyor_from(args)
    if not conveyor.moving:
        return None
    plan = plan_belt_cycle(args.start, args.pick, args.place, config, conveyor,
                           pick_dwell=args.pick_dwell, latch_time=args.pick_time)
    result = dict(plan.metrics)
    result.update({'start': list(args.start), 'pick': list(args.pick),
                   'pick_time': args.pick_time, 'place': list(args.place),
                   'conveyor_velocity': list(args.conveyor_velocity),
                   'pick_position': None if plan.intercept is None
                   else plan.intercept.pick_position.tolist(),
                   'end_position': plan.end_position.tolist()})
    return _with_trajectory(result, plan.joint_trajectory)


def _format_belt(result):
    """Return a short human-readable summary of a belt cycle (planned and executed peaks)."""
    lines = [f"belt cycle: {result['duration'] * 1e3:.5g} ms, {result['n_points']} points; "
             f"pick at {result['belt.pick_after_start']:.6g} s (after a wait of "
             f"{result['belt.wait'] * 1e3:.4g} ms), at {result['belt.window_position']:.4g} m "
             f"along the belt, {result['belt.margin_distance']:.4g} m "
             f"({result['belt.margin_time']:.4g} s) before the window's end"]
    for leg in ('approach', 'transfer'):
        for kind in ('planned', 'executed'):
            lines.append(
                f"{leg} {kind} peaks (base frame): {result[f'{leg}.{kind}.peak_speed']:.5g} "
                f"m/s, {result[f'{leg}.{kind}.peak_accel']:.5g} m/s^2, "
                f"{result[f'{leg}.{kind}.peak_jerk']:.5g} m/s^3")
    return '\n'.join(lines) + '\n'


def _with_trajectory(result, trajectory):
    result.update({
        'joint_names': list(trajectory.joint_names),
        'joint_trajectory': {
            'time_from_start': trajectory.time_from_start.tolist(),
            'positions': trajectory.positions.tolist(),
            'velocities': trajectory.velocities.tolist(),
            'accelerations': trajectory.accelerations.tolist(),
        },
    })
    return result


def plan_result(args):
    """Plan one transfer (or, on a moving belt, a whole cycle); return the JSON-ready dict."""
    config = _config_from(args)
    belt = _belt_result(args, config)
    if belt is not None:
        return belt
    leg = plan_transfer(args.pick, args.place, config)
    result = leg.summary()
    result.update({'pick': list(args.pick), 'place': list(args.place)})
    return _with_trajectory(result, leg.joint_trajectory)


def _format_human(result):
    """Return a short human-readable summary of a plan."""
    def number(key, scale=1.0, digits=5):
        value = result.get(key)
        return 'n/a' if value is None else f'{value * scale:.{digits}g}'
    lines = [
        f"path: {number('path_length')} m (arc {number('arc_length')} m exact, "
        f"{number('arc_length_approx')} m by eq. 27)",
        f"arc: l {number('l')} m, h {number('h')} m, phi {number('phi_deg')} deg, "
        f"a {number('a')} m, b {number('b')} m",
        f"theta_T1 {number('theta_T1_deg')} deg, theta_T2 {number('theta_T2_deg')} deg, "
        f"apex height {number('apex_height')} m",
        f"motion ({result['profile']}): {number('duration', 1e3)} ms, segments "
        + ' / '.join(f'{value * 1e3:.4g}' for value in result['segment_durations']) + ' ms',
    ]
    for kind in ('planned', 'executed'):
        lines.append(
            f"{kind} peaks: {number(kind + '.peak_speed')} m/s, "
            f"{number(kind + '.peak_accel')} m/s^2, {number(kind + '.peak_jerk')} m/s^3; "
            f"joints {number(kind + '.joint_peak_velocity')} rad/s, "
            f"{number(kind + '.joint_peak_accel')} rad/s^2")
    lines.append(f"joint trajectory: {result['n_points']} points, executed deviation at most "
                 f"{number('executed.max_interpolation_error', 1e3)} mm")
    return '\n'.join(lines) + '\n'


def _report_error(args, kind, message):
    if args.json:
        sys.stdout.write(json.dumps({'error': {'kind': kind, 'message': message}}) + '\n')
    else:
        sys.stderr.write(f'ellipath plan: {kind}: {message}\n')


def _run_plan(args):
    try:
        result = plan_result(args)
    except EllipathError as error:
        _report_error(args, error.kind, str(error))
        return 2
    except (ArithmeticError, ValueError) as error:
        # A bug, not a rejected input: say so in the same shape, with exit status 1.
        _report_error(args, 'internal', f'{type(error).__name__}: {error}')
        return 1
    if args.json:
        sys.stdout.write(json.dumps(_finite(result), allow_nan=False) + '\n')
    else:
        sys.stdout.write(_format_belt(result) if 'belt.pick_after_start' in result
                         else _format_human(result))
    return 0


def _finite(value):
    """Replace non-finite floats (none are expected) by None so the JSON stays valid."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    return value


def _run_bench(args):
    from ellipath_ros.bench import format_report, run_bench
    try:
        result = run_bench('quick' if args.quick else 'full', pairs=args.pairs,
                           e2e_pairs=args.e2e_pairs, seed=args.seed, domain_id=args.domain_id)
    except ImportError as error:
        if args.json:
            sys.stdout.write(json.dumps({'error': {'kind': 'missing_dependency',
                                                   'message': str(error)}}) + '\n')
        else:
            sys.stderr.write(f'ellipath bench: {error}\n')
        return 2
    if args.json:
        sys.stdout.write(json.dumps(_finite(result), allow_nan=False) + '\n')
    else:
        sys.stdout.write(format_report(result))
    # The end-to-end section failed (the node did not start or answer): say so by the status.
    return 1 if 'error' in result['latency_notes']['e2e_ms'] else 0


def _run_plot(args):
    try:
        from ellipath_ros.paper.plotting import write_figures
        config = _config_from(args)
        conveyor = _conveyor_from(args)
        if conveyor.moving:
            plan = plan_belt_cycle(args.start, args.pick, args.place, config, conveyor,
                                   pick_dwell=args.pick_dwell, latch_time=args.pick_time)
            written = [write_belt_figure(plan, np.array(args.pick), conveyor.velocity,
                                         args.pick_time, args.out)]
        else:
            written = write_figures(args.pick, args.place, args.out, config)
    except ImportError as error:
        sys.stderr.write(f'ellipath plot: {error}\n')
        return 2
    except EllipathError as error:
        sys.stderr.write(f'ellipath plot: {error.kind}: {error}\n')
        return 2
    for path in written:
        sys.stdout.write(f'{path}\n')
    return 0


def _run_demo(args):
    from ellipath_ros.demo import run_demo
    return run_demo(args)


def build_parser():
    """Return the argument parser of the ``ellipath`` command."""
    parser = _Parser(
        prog='ellipath', description='Elliptical pick-and-place planning for Delta robots '
        '(Choe et al., 2023), beyond the paper where it is weak.')
    commands = parser.add_subparsers(dest='command', required=True)
    plan = commands.add_parser('plan', help='plan one pick-and-place transfer')
    _add_plan_arguments(plan)
    _add_belt_arguments(plan)
    plan.set_defaults(run=_run_plan)
    plot = commands.add_parser('plot', help="write the paper's figures for a pick/place as PNG")
    _add_plan_arguments(plot)
    _add_belt_arguments(plot)
    plot.add_argument('--out', default='figures', help='output folder (default: %(default)s)')
    plot.set_defaults(run=_run_plot)
    # The demo's options and argument types (importing the demo needs no ROS).
    from ellipath_ros.demo import _domain_id, _positive_int, add_arguments
    bench = commands.add_parser(
        'bench', help='planning latency, end-to-end latency, cycle times against the TOPP-RA '
        'bound, executed peaks and picks/min (needs .[bench])')
    bench.add_argument('--quick', action='store_true',
                       help='fewer pairs and shorter budgets: about 30 s instead of 3 min')
    bench.add_argument('--json', action='store_true', help='print one JSON object')
    bench.add_argument('--pairs', type=_positive_int, default=None,
                       help='random pick/place pairs of the in-process sections (default: '
                       '1000, 150 with --quick)')
    bench.add_argument('--e2e-pairs', type=_positive_int, default=None,
                       help='pairs sent to the node process (default: 100, 15 with --quick)')
    bench.add_argument('--seed', type=int, default=None,
                       help='seed of the random pairs (default: 2023)')
    bench.add_argument('--domain-id', type=_domain_id, default=None,
                       help='ROS domain of the node process (default: ROS_DOMAIN_ID if set, '
                       'else 78); DDS stays on this host')
    bench.set_defaults(run=_run_bench)
    demo = commands.add_parser(
        'demo', help='start the node, send pick/place pairs, judge the executed motion')
    add_arguments(demo)
    demo.set_defaults(run=_run_demo)
    return parser


def main(argv=None):
    """Run the ``ellipath`` command; return the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = build_parser().parse_args(argv)
    except _ArgumentsRejected as error:
        message = f'{error.parser.prog}: {error}'
        if '--json' in argv:
            sys.stdout.write(json.dumps({'error': {'kind': 'invalid_arguments',
                                                   'message': message}}) + '\n')
        else:
            # argparse's own report: usage, then the reason.
            error.parser.print_usage(sys.stderr)
            sys.stderr.write(f'{error.parser.prog}: error: {error}\n')
        return 2
    try:
        return args.run(args)
    except KeyboardInterrupt:
        return 130


if __name__ == '__main__':
    sys.exit(main())
