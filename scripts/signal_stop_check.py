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
Does ``ellipath_node`` stop on ONE signal? Start it, let it idle, send one signal, wait.

Each run starts the node command, waits for its ``ready`` log line, then a random 4-5 s
(``--idle``), sends exactly one SIGINT (or SIGTERM, ``--signal TERM``) and waits ``--wait``
s. The idle time counts from the ready line: a signal before the node has installed its
handlers (during the imports, over 4 s on a loaded machine) tests Python's start-up, not the
node. With ``--pairs N`` the node is first sent N pick_place pairs (from this process, once
its subscription is matched) and the idle time counts from them: with ``--slow-plan`` (the
paper's curvature profile sampled every 0.1 ms, plans of a second or more) and a short
``--idle`` the signal comes while a plan runs, and with N above ``queue_depth`` (10) while
the queue is full. Each run's node has a namespace of its own (``--jobs`` run side by side).
The child inherits this script's signal dispositions: started in the background of a
non-interactive shell (``cmd &``), it starts with SIGINT ignored. A node still alive then is
counted as hung: it gets SIGABRT, which (``PYTHONFAULTHANDLER=1`` is set for the child)
dumps the Python stack of every thread to its stderr, saved under ``--log-dir``. A node
that exits with a status other than 0 or writes a traceback is counted too.

Example (issue 13, item 5)::

    ROS_DOMAIN_ID=40 .venv/bin/python scripts/signal_stop_check.py --runs 25
    ROS_DOMAIN_ID=40 .venv/bin/python scripts/signal_stop_check.py --runs 25 \
        --pairs 12 --slow-plan --idle 0 1

Not part of the test suite: 25 runs take about 3 minutes.
"""

import argparse
from concurrent.futures import ThreadPoolExecutor
import os
from pathlib import Path
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

from geometry_msgs.msg import Pose
from geometry_msgs.msg import PoseArray
import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.signals import SignalHandlerOptions

DEFAULT_COMMAND = str(Path(sys.executable).parent / 'ellipath_node')
# Parameters that make each plan slow (seconds): a signal after a pair then comes mid-plan.
SLOW_PLAN = ('-p', 'output_mode:=samples', '-p', 'sample_period:=0.0001',
             '-p', 'profile:=curvature', '-p', 'join:=paper')
# Picks and places of the pairs sent, alternating (reachable, in the default workspace).
PAIR_POINTS = ((0.10, 0.05, -0.85), (-0.15, -0.10, -0.82), (0.12, -0.08, -0.88))
MATCH_TIMEOUT = 60.0  # s, for the node's pick_place subscription to be matched


class PairSender:
    """Publishers of pick_place pairs to the nodes' namespaces, in a context of this process."""

    def __init__(self):
        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('signal_stop_check', context=self.context)
        self._lock = threading.Lock()  # publishers are created from the runs' threads

    def send(self, namespace, count):
        """Send ``count`` pairs to ``namespace``/pick_place once matched; return if delivered."""
        with self._lock:
            publisher = self.node.create_publisher(PoseArray, f'{namespace}/pick_place', 100)
        try:
            deadline = time.monotonic() + MATCH_TIMEOUT
            while publisher.get_subscription_count() == 0:
                if time.monotonic() > deadline:
                    return False
                time.sleep(0.05)
            for index in range(count):
                message = PoseArray()
                message.header.frame_id = 'base_link'
                for point in (PAIR_POINTS[index % 3], PAIR_POINTS[(index + 1) % 3]):
                    pose = Pose()
                    pose.position.x, pose.position.y, pose.position.z = point
                    pose.orientation.w = 1.0
                    message.poses.append(pose)
                publisher.publish(message)
            # Reliable: the writer must live until the node has them.
            return publisher.wait_for_all_acked(Duration(seconds=MATCH_TIMEOUT))
        finally:
            with self._lock:
                self.node.destroy_publisher(publisher)

    def close(self):
        """Shut this process's ROS side down."""
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _process_state(pid, log_path):
    """Write the signal masks of ``pid`` and whether its main thread still wakes up."""
    # A file of its own: the node's abort dump would overwrite it in the log.
    log_path = Path(f'{log_path}.proc')
    status = Path(f'/proc/{pid}/status')
    switches = Path(f'/proc/{pid}/task/{pid}/status')

    def wakeups():
        for line in switches.read_text().splitlines():
            if line.startswith('voluntary_ctxt_switches'):
                return int(line.split()[1])
        return -1

    with open(log_path, 'a') as log:
        log.write('\n--- /proc status (SIGINT is bit 2, SIGTERM bit 15, hex masks) ---\n')
        log.writelines(line + '\n' for line in status.read_text().splitlines()
                       if line.startswith(('SigQ', 'SigPnd', 'ShdPnd', 'SigBlk', 'SigIgn',
                                           'SigCgt')))
        before = wakeups()
        time.sleep(1.0)
        log.write(f'main thread voluntary context switches in 1 s: {wakeups() - before}\n')


def _native_stacks(pid, log_path):
    """Append the native stack of every thread of ``pid`` (gdb, if installed) to the log."""
    _process_state(pid, log_path)
    if shutil.which('gdb') is None:
        return
    with open(log_path, 'a') as log:
        log.write('\n--- gdb: thread apply all bt ---\n')
        log.flush()
        subprocess.run(['gdb', '-p', str(pid), '-batch', '-ex', 'thread apply all bt'],
                       stdout=log, stderr=subprocess.STDOUT, timeout=60.0, check=False)


def _wait_ready(process, log_path, timeout=60.0):
    """Wait until the node logs its ready line; return whether it did."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and process.poll() is None:
        if 'ready:' in Path(log_path).read_text():
            return True
        time.sleep(0.05)
    return False


def run_once(command, sig, idle, wait, log_path, gdb=False, from_start=False, pairs=0,
             sender=None, namespace='/signal_stop_check', start_timeout=60.0):
    """Start ``command``, idle, send ``sig`` once; return (outcome, seconds to exit)."""
    env = dict(os.environ, PYTHONFAULTHANDLER='1', PYTHONUNBUFFERED='1',
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    with open(log_path, 'w') as log:
        process = subprocess.Popen(command, env=env, stdout=log, stderr=subprocess.STDOUT)
        if not from_start and not _wait_ready(process, log_path, start_timeout):
            process.kill()
            process.wait()
            return 'never ready', None
        if pairs and not sender.send(namespace, pairs):
            process.kill()
            process.wait()
            return 'pairs not delivered', None
        time.sleep(idle)
        if process.poll() is not None:
            return f'exited early ({process.returncode})', None
        sent = time.monotonic()
        process.send_signal(sig)
        try:
            process.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            if gdb:
                _native_stacks(process.pid, log_path)
            process.send_signal(signal.SIGABRT)  # faulthandler dumps every thread's stack
            try:
                process.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
            return 'hung', None
        elapsed = time.monotonic() - sent
    output = Path(log_path).read_text()
    if process.returncode != 0:
        return f'exit status {process.returncode}', elapsed
    if 'Traceback' in output:
        return 'traceback', elapsed
    return 'ok', elapsed


def main():
    """Run the check ``--runs`` times and print a summary; exit 1 if any run failed."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--runs', type=int, default=25)
    parser.add_argument('--signal', choices=('INT', 'TERM'), default='INT')
    parser.add_argument('--idle', type=float, nargs=2, default=(4.0, 5.0), metavar=('MIN', 'MAX'),
                        help='seconds between start and the signal, drawn uniformly')
    parser.add_argument('--wait', type=float, default=10.0,
                        help='seconds after the signal before the node counts as hung')
    parser.add_argument('--log-dir', default=None, help='where to keep each run output')
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--jobs', type=int, default=1, help='nodes run at the same time')
    parser.add_argument('--from-start', action='store_true',
                        help='count the idle time from the process start, not the ready line')
    parser.add_argument('--gdb', action='store_true',
                        help='before aborting a hung node, log the native stacks with gdb')
    parser.add_argument('--start-timeout', type=float, default=60.0,
                        help='seconds a node may take to its ready line (else: never ready)')
    parser.add_argument('--pairs', type=int, default=0,
                        help='pick_place pairs sent once the node is ready; idle counts from them')
    parser.add_argument('--slow-plan', action='store_true',
                        help='start the node with parameters that make each plan slow')
    parser.add_argument('command', nargs='*', default=[DEFAULT_COMMAND],
                        help='node command (default: the ellipath_node next to this python)')
    options = parser.parse_args()
    log_dir = Path(options.log_dir or tempfile.mkdtemp(prefix='signal_stop_'))
    log_dir.mkdir(parents=True, exist_ok=True)
    sig = getattr(signal, f'SIG{options.signal}')
    rng = random.Random(options.seed)
    failures = []
    exit_times = []
    idles = [rng.uniform(*options.idle) for _ in range(options.runs)]
    sender = PairSender() if options.pairs else None
    tag = f'signal_stop_check_{os.getpid()}'

    def one(run):
        namespace = f'/{tag}_{run}'
        command = [*options.command, '--ros-args', '-r', f'__ns:={namespace}',
                   *(SLOW_PLAN if options.slow_plan else ())]
        return run_once(command, sig, idles[run], options.wait,
                        log_dir / f'run_{run:03d}.log', options.gdb, options.from_start,
                        options.pairs, sender, namespace, options.start_timeout)

    try:
        with ThreadPoolExecutor(options.jobs) as pool:
            outcomes = list(pool.map(one, range(options.runs)))
    finally:
        if sender is not None:
            sender.close()
    for run, (outcome, elapsed) in enumerate(outcomes):
        log_path = log_dir / f'run_{run:03d}.log'
        if outcome == 'ok':
            exit_times.append(elapsed)
        else:
            failures.append((run, outcome, log_path))
        print(f'run {run + 1}/{options.runs}: {outcome}'
              + (f' ({elapsed:.2f} s after SIG{options.signal})' if elapsed else ''),
              flush=True)
    print(f'\n{len(failures)} of {options.runs} runs failed to stop cleanly on one '
          f'SIG{options.signal} within {options.wait:g} s')
    if exit_times:
        print(f'clean exits: {min(exit_times):.2f} to {max(exit_times):.2f} s after the signal')
    # The node's last resort (STOP_DEADLINE in node.py) logs this before it ends the process.
    forced = [run for run in range(options.runs)
              if 'exiting now' in (log_dir / f'run_{run:03d}.log').read_text()]
    print(f'{len(forced)} of {options.runs} runs ended by the last resort (orderly shutdown '
          f'stuck): {[run + 1 for run in forced]}')
    for run, outcome, log_path in failures:
        print(f'  run {run + 1}: {outcome}, output in {log_path}')
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main())
