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
Flood ``ellipath_node`` with pick/place pairs from another process (issue 13, item 3).

Starts the node (``python -m ellipath_ros.node_entry``, the ``ellipath_node`` command, the code
of this checkout) as a subprocess, then offers ``--rate`` pairs per second for ``--seconds``:
with ``--stream pick_place`` each pair as one ``pick_place`` PoseArray, with ``two_topic`` as
``pick_pose`` then ``place_pose`` with a stamp of their own (``stamp`` pairing), with ``mixed``
(default) even pair ids one way and odd ones the other. Every pair is identifiable: its id is
written into the pick's and the place's x and y. About ``--invalid`` of them are invalid (a NaN
place, or a wrong frame). The publishers are RELIABLE/KEEP_ALL, as the node asks of senders:
when the node reads slower, ``publish()`` blocks and then raises (back-pressure); such a
message is counted as refused (a pair whose pick was refused is not sent on; one whose place
was refused leaves its pick at the node). Records every ``/diagnostics`` status and every
trajectory, samples the node's VmRSS, lets the queue drain, sends one more valid pair and
checks:

* the node is alive and answers that pair (its trajectory arrives);
* no trajectory joins a place with a pick it was not sent with (FK of its points);
* every trajectory passes ``validate_jtc``;
* the ledger: sent = refused at the sender + received by the node, for pairs (pick_place and
  place_pose messages) and for pick_pose messages; the node's pairs: received = released +
  rejected (by kind) + dropped (by kind) + queued + releasing; its picks: received = paired +
  pending + invalid + replaced + evicted + cleared; every pair number it counted has a
  status;
* the queue length stayed within ``queue_depth``;
* latency under load (``plan_time``, ``receive_to_plan_latency``,
  ``receive_to_publish_latency`` of the statuses, and send to trajectory arrival measured
  here; *planned*/*released*, not executed).

Prints the report as JSON; exit status 1 if a check failed. DDS stays on this host; give
the run a domain of its own::

    ROS_DOMAIN_ID=121 .venv/bin/python scripts/flood.py --rate 1000 --seconds 60 \
        --stream pick_place
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from ellipath_ros.conversions import joint_trajectory_data
from ellipath_ros.conversions import numbers_in_ranges
from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import validate_jtc
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.node import INTAKE_QOS
from geometry_msgs.msg import Pose
from geometry_msgs.msg import PoseArray
from geometry_msgs.msg import PoseStamped
import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from trajectory_msgs.msg import JointTrajectory

FRAME = 'base_link'
# Pair ids are written into the positions: x = X0 + STEP * (id % ROW), y = Y0 + STEP * (id //
# ROW) for the pick; the place is the pick mirrored in x and shifted by PLACE_SHIFT in y. The
# grid stays inside the default safe workspace for up to ROW * ROWS pairs.
X0, Y0, STEP, ROW, ROWS = -0.15, -0.12, 1e-4, 3000, 2000
PICK_Z, PLACE_Z, PLACE_SHIFT = -0.85, -0.8, 0.05
# A trajectory point is "the pick" if FK puts it this close to it [m]; pair ids are STEP
# apart, so a pick of another pair is at least 100 µm away.
PICK_TOLERANCE = 1e-6
# Queue depth of this process's subscriptions: nothing is lost on our side.
DEPTH = 100_000
STREAMS = ('mixed', 'pick_place', 'two_topic')
# Pair counters of the node; the pick counters; see EllipathNode._queue_values.
PAIR_OUTCOMES = ('released', 'rejected', 'dropped', 'queued', 'releasing')
PICK_OUTCOMES = ('paired', 'pending', 'invalid', 'replaced', 'evicted', 'cleared')
# How long the node may take to start, to drain its queue, and to answer the last pair [s].
START_TIMEOUT = 60.0
DRAIN_TIMEOUT = 120.0
ANSWER_TIMEOUT = 10.0
PAIR_IN_MESSAGE = re.compile(r'^pair (\d+)\b')


def pick_of(pair_id):
    """Return the pick position of pair ``pair_id``."""
    return np.array([X0 + STEP * (pair_id % ROW), Y0 + STEP * (pair_id // ROW), PICK_Z])


def place_of(pair_id):
    """Return the place position of pair ``pair_id``."""
    pick = pick_of(pair_id)
    return np.array([-pick[0], pick[1] + PLACE_SHIFT, PLACE_Z])


def pair_of_place(place):
    """Return the id of the pair whose place is ``place`` (nearest on the grid)."""
    column = round((-place[0] - X0) / STEP)
    row = round((place[1] - PLACE_SHIFT - Y0) / STEP)
    return row * ROW + column


# Lines of /proc/<pid>/status with the resident set size and its parts [KiB]: anonymous
# (malloc, Python, NumPy), file-backed (libraries, which grow as new code runs) and shared
# memory (Fast DDS's shared-memory transport).
MEMORY_FIELDS = {'VmRSS': 'rss', 'RssAnon': 'anon', 'RssFile': 'file', 'RssShmem': 'shmem'}


def memory_kib(pid):
    """Return VmRSS and its parts (see MEMORY_FIELDS) of process ``pid`` [KiB], or None."""
    memory = {}
    try:
        with open(f'/proc/{pid}/status') as status:
            for line in status:
                name = line.split(':', 1)[0]
                if name in MEMORY_FIELDS:
                    memory[MEMORY_FIELDS[name]] = int(line.split()[1])
    except OSError:
        return None
    return memory if 'rss' in memory else None


def cpu_seconds(pid):
    """Return the CPU time (user + system) process ``pid`` has used [s], or None if gone."""
    try:
        with open(f'/proc/{pid}/stat') as stat:
            # Fields after the command name (which may hold spaces): utime, stime are 14, 15.
            fields = stat.read().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def resident_kib(pid):
    """Return the resident set size (VmRSS) of process ``pid`` [KiB], or None if it is gone."""
    memory = memory_kib(pid)
    return None if memory is None else memory['rss']


def percentile(values, share):
    """Return the ``share`` quantile of ``values`` (nearest rank), or None if empty."""
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, math.ceil(share * len(ordered)) - 1))]


def _pose(position):
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(value) for value in position)
    pose.orientation.w = 1.0
    return pose


class Recorder:
    """This process's ROS side: the three publishers and a record of what the node sends."""

    def __init__(self, domain_id):
        self.context = Context()
        # No rclpy signal handlers: Ctrl-C raises KeyboardInterrupt, and run() stops the node.
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('ellipath_flood', context=self.context)
        # RELIABLE/KEEP_ALL, as the node asks of senders (its own INTAKE_QOS).
        self.pick_place = self.node.create_publisher(PoseArray, 'pick_place', INTAKE_QOS)
        self.pick_pose = self.node.create_publisher(PoseStamped, 'pick_pose', INTAKE_QOS)
        self.place_pose = self.node.create_publisher(PoseStamped, 'place_pose', INTAKE_QOS)
        qos = QoSProfile(depth=DEPTH)
        self.statuses = []  # (arrival time.monotonic(), DiagnosticStatus)
        self.trajectories = []  # (arrival time.monotonic(), JointTrajectory)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                      qos)
        self.node.create_subscription(JointTrajectory, 'joint_trajectory',
                                      self._on_trajectory, qos)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._spinner = threading.Thread(target=self._spin, daemon=True)
        self._spinner.start()

    def _spin(self):
        try:
            while self.context.ok():
                self.executor.spin_once(timeout_sec=0.05)
        except ExternalShutdownException:
            pass  # close() shut the context down while the executor waited

    def _on_diagnostics(self, message):
        now = time.monotonic()
        self.statuses.extend((now, status) for status in message.status)

    def _on_trajectory(self, message):
        self.trajectories.append((time.monotonic(), message))

    def connected(self):
        """Return True once the node's subscriptions and publishers are matched."""
        return (all(publisher.get_subscription_count() > 0 for publisher in
                    (self.pick_place, self.pick_pose, self.place_pose))
                and self.node.count_publishers('/diagnostics') > 0
                and self.node.count_publishers('joint_trajectory') > 0)

    def send(self, pair_id, stamp_sec, stream='mixed', invalid=None):
        """
        Send pair ``pair_id``; return (topic, outcome).

        ``invalid`` is None, 'nan' or 'frame'. topic: 'pick_place' or 'two_topic'; outcome:
        'sent', 'refused' (nothing of the pair reached DDS) or 'place_refused' (its pick
        did).
        """
        pick, place = pick_of(pair_id), place_of(pair_id)
        if invalid == 'nan':
            place[2] = math.nan
        frame = 'not_' + FRAME if invalid == 'frame' else FRAME
        if stream == 'pick_place' or (stream == 'mixed' and pair_id % 2 == 0):
            message = PoseArray()
            message.header.frame_id = frame
            message.header.stamp.sec = stamp_sec
            message.poses = [_pose(pick), _pose(place)]
            return 'pick_place', 'sent' if publish(self.pick_place, message) else 'refused'
        for publisher, position, refused in ((self.pick_pose, pick, 'refused'),
                                             (self.place_pose, place, 'place_refused')):
            message = PoseStamped()
            message.header.frame_id = frame
            message.header.stamp.sec = stamp_sec  # unique per pair: 'stamp' pairing
            message.pose = _pose(position)
            if not publish(publisher, message):
                return 'two_topic', refused
        return 'two_topic', 'sent'

    def close(self):
        """Shut this process's ROS side down."""
        rclpy.try_shutdown(context=self.context)
        self._spinner.join(2.0)
        self.node.destroy_node()


def publish(publisher, message):
    """
    Publish; return False if DDS refused the message (back-pressure), else True.

    A RELIABLE/KEEP_ALL writer whose history is full (the node has not read what it holds)
    blocks up to its max_blocking_time (Fast DDS: 100 ms) and then fails: rclpy raises
    RCLError, a RuntimeError, 'cannot publish data'. The message was not sent.
    """
    try:
        publisher.publish(message)
    except RuntimeError:
        return False
    return True


def start_node(log_path, env):
    """Start ellipath_node (this checkout's code); return the Popen once it is ready."""
    log = open(log_path, 'w')
    process = subprocess.Popen([sys.executable, '-m', 'ellipath_ros.node_entry'], env=env,
                               stdout=log, stderr=subprocess.STDOUT)
    log.close()
    deadline = time.monotonic() + START_TIMEOUT
    while time.monotonic() < deadline:
        with open(log_path) as text:
            if 'ready' in text.read():
                return process
        if process.poll() is not None:
            break
        time.sleep(0.1)
    process.kill()
    raise RuntimeError(f'ellipath_node did not start, see {log_path}')


def _values(status):
    return {item.key: item.value for item in status.values}


def status_pairs(status, values):
    """
    Return the numbers of the pairs a status is about (none: pick_pose, clear_queue).

    ``pair``, or ``pairs`` (ranges: the pairs a full queue rejected in one status period),
    else a message starting "pair <number>".
    """
    if 'pair' in values:
        return [int(values['pair'])]
    if 'pairs' in values:
        return numbers_in_ranges(values['pairs'])
    match = PAIR_IN_MESSAGE.match(status.message)
    return [int(match.group(1))] if match else []


def check_trajectories(trajectories, sent_ids, geometry):
    """
    Return (released, mis-pairings, invalid trajectories) of the trajectories.

    released: (pair id, arrival time) of each trajectory that joins a sent pair's pick and
    place.
    """
    released, mispaired, invalid = [], [], []
    for arrival, message in trajectories:
        try:
            data = joint_trajectory_data(message)
            validate_jtc(data)
        except EllipathError as error:
            invalid.append(str(error))
            continue
        tcp = forward_kinematics(np.asarray(data.positions), geometry)
        pair_id = pair_of_place(tcp[-1])
        if (pair_id not in sent_ids
                or np.linalg.norm(tcp[-1] - place_of(pair_id)) > PICK_TOLERANCE
                or np.min(np.linalg.norm(tcp - pick_of(pair_id), axis=1)) > PICK_TOLERANCE):
            mispaired.append({'place': tcp[-1].tolist(), 'nearest_pair': pair_id})
            continue
        released.append((pair_id, arrival))
    return released, mispaired, invalid


def run(rate, seconds, seed=1, rss_every=1.0, invalid_share=0.02, log_dir=None, out=None,
        drain_timeout=DRAIN_TIMEOUT, stream='mixed', warm_up=None):
    """
    Flood a fresh node and return the report (a dict); see the module docstring.

    Pairs are offered at ``rate`` for ``seconds`` (wall time): a pair not yet offered when
    the time is up (the sender was slowed by refusals) is not sent. ``warm_up``: (pairs,
    rate) offered first, at that rate, within the ``seconds`` (scripts/soak.py). ``out`` (a
    file) receives progress lines, e.g. RSS samples; None for silence.
    """
    warm_up_pairs, warm_up_rate = warm_up or (0, rate)
    warm_up_seconds = warm_up_pairs / warm_up_rate
    domain_id = int(os.environ.get('ROS_DOMAIN_ID', '0'))
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_DOMAIN_ID=str(domain_id), PYTHONUNBUFFERED='1')
    log_dir = log_dir or tempfile.mkdtemp(prefix='ellipath_flood_')
    os.makedirs(log_dir, exist_ok=True)
    log_path = os.path.join(log_dir, 'node.log')
    rng = np.random.default_rng(seed)
    recorder = Recorder(domain_id)
    try:
        process = start_node(log_path, env)
    except RuntimeError:
        recorder.close()
        raise
    try:
        deadline = time.monotonic() + START_TIMEOUT
        while not recorder.connected() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)  # discovery is matched both ways by now, give DDS a moment more
        rss = [(0.0, resident_kib(process.pid))]
        cpu_at_start = cpu_seconds(process.pid)
        memory = []  # one sample per rss_every: see _memory_sample
        offered = warm_up_pairs + int(round(rate * max(0.0, seconds - warm_up_seconds)))
        sent, sent_at, invalid = {}, {}, {}
        started = time.monotonic()
        next_sample = started + rss_every
        for pair_id in range(offered):
            due = started + (pair_id / warm_up_rate if pair_id < warm_up_pairs else
                             warm_up_seconds + (pair_id - warm_up_pairs) / rate)
            now = time.monotonic()
            if now >= started + seconds:
                break  # slowed down by refusals: the time is up
            if due > now:
                time.sleep(due - now)
            kind = None
            if rng.uniform() < invalid_share:
                kind = 'nan' if rng.uniform() < 0.5 else 'frame'
                invalid[pair_id] = kind
            sent[pair_id] = recorder.send(pair_id, 1_000_000 + pair_id, stream, kind)
            sent_at[pair_id] = time.monotonic()
            if now >= next_sample:
                rss.append((now - started, resident_kib(process.pid)))
                memory.append(_memory_sample(process.pid, now - started, pair_id + 1,
                                             recorder))
                next_sample += rss_every
                if out is not None:
                    print(json.dumps({'t': round(now - started, 1), 'offered': pair_id + 1,
                                      'refused': _refused(sent), 'rss_kib': rss[-1][1]}),
                          file=out, flush=True)
        send_time = time.monotonic() - started
        node_cpu = {'start': cpu_at_start, 'sending': cpu_seconds(process.pid)}
        expected_pairs = sum(outcome == 'sent' for _, outcome in sent.values())
        # Drain: wait until the node has counted every pair sent and its queue is empty.
        drained = False
        deadline = time.monotonic() + drain_timeout
        while time.monotonic() < deadline and process.poll() is None:
            latest = _latest_counts(recorder.statuses)
            if (latest and int(latest['pairs_received']) >= expected_pairs
                    and latest.get('queue_length') == '0'
                    and time.monotonic() > recorder.statuses[-1][0] + 2.0):
                drained = True
                break
            time.sleep(0.2)
        drain_time = time.monotonic() - started - send_time
        rss.append((time.monotonic() - started, resident_kib(process.pid)))
        # The last pair: does the node still answer, and how fast?
        probe_id = len(sent)
        trajectories_before = len(recorder.trajectories)
        probe_sent = time.monotonic()
        sent[probe_id] = recorder.send(probe_id, 1_000_000 + probe_id, stream)
        sent_at[probe_id] = time.monotonic()
        answer = None
        while time.monotonic() < probe_sent + ANSWER_TIMEOUT and answer is None:
            for arrival, message in recorder.trajectories[trajectories_before:]:
                tcp = forward_kinematics(np.asarray(message.points[-1].positions),
                                         PlannerConfig().geometry)
                if pair_of_place(tcp) == probe_id:
                    answer = arrival - probe_sent
            time.sleep(0.05)
        time.sleep(1.0)  # the probe's 'released' status follows its trajectory
        alive = process.poll() is None
        rss.append((time.monotonic() - started, resident_kib(process.pid)))
    finally:
        process.send_signal(2)
        try:
            exit_code = process.wait(15.0)
        except subprocess.TimeoutExpired:
            process.kill()
            exit_code = 'killed'
        recorder.close()
    report = _report(recorder, sent, sent_at, invalid, rss, started, alive, exit_code, answer,
                     log_path)
    report['memory_samples'] = memory
    loads = [sample['load1'] for sample in memory]
    report['load_average_1min'] = {'min': min(loads, default=None),
                                   'max': max(loads, default=None)}
    # The node's CPU time while pairs were sent (intake, planning and releases together).
    report['node_cpu_s_while_sending'] = (
        None if None in node_cpu.values() else round(node_cpu['sending'] - node_cpu['start'], 1))
    report.update(stream=stream, rate_offered=rate, seconds=seconds, pairs_offered=offered,
                  send_time_s=round(send_time, 2), drained=drained,
                  drain_time_s=round(drain_time, 1),
                  rate_achieved=round((len(sent) - 1) / send_time, 1))
    report['ok'] = report['ok'] and drained
    return report


def _memory_sample(pid, elapsed, offered, recorder):
    """
    Return the node's memory (see memory_kib) with what it had sent and this process offered.

    ``statuses`` and ``trajectories``: how many the node had published and this process
    received by then, which fill the node's bounded DDS histories (scripts/soak.py).
    """
    return {'t': round(elapsed, 1), 'offered': offered, 'statuses': len(recorder.statuses),
            'trajectories': len(recorder.trajectories), 'load1': os.getloadavg()[0],
            **(memory_kib(pid) or {})}


def _refused(sent):
    """Return how many pairs of ``sent`` were refused, in whole or their place."""
    return sum(outcome != 'sent' for _, outcome in sent.values())


def _latest_counts(statuses):
    """Return the values of the status with the highest pairs_received so far, or None."""
    best = None
    for _, status in statuses[-200:]:
        values = _values(status)
        if 'pairs_received' in values and (
                best is None or int(values['pairs_received']) >= int(best['pairs_received'])):
            best = values
    return best


def sender_ledger(sent):
    """
    Return what this process did with its pairs: per topic, sent and refused.

    'pairs': pick_place and place_pose messages (one per pair); 'picks': pick_pose messages.
    """
    ledger = {'pairs_attempted': len(sent), 'pairs_sent': 0, 'pairs_refused': 0,
              'picks_attempted': 0, 'picks_sent': 0, 'picks_refused': 0}
    for topic, outcome in sent.values():
        ledger['pairs_sent' if outcome == 'sent' else 'pairs_refused'] += 1
        if topic == 'two_topic':
            ledger['picks_attempted'] += 1
            ledger['picks_refused' if outcome == 'refused' else 'picks_sent'] += 1
    return ledger


def expected_rejections(sent, invalid):
    """
    Return how many pairs sent the node must reject, by kind: invalid_input and unpaired.

    A NaN place is invalid_input on both streams, as is a pair in a wrong frame: a pick_pose
    in a wrong frame is rejected itself, and its place, in the same wrong frame, is rejected
    as invalid_input for its own frame (a place with no pick waits for it only if it is
    valid). Every other pair sent is valid: none may be rejected as either (a valid place
    read before its pick waits for it: unpaired only if its pick was lost).
    """
    expected = {'invalid_input': 0, 'unpaired': 0}
    for pair_id in invalid:
        _, outcome = sent[pair_id]
        if outcome == 'sent':
            expected['invalid_input'] += 1
    return expected


def node_ledger(values):
    """Return the node's pair and pick counters from a status's values, and the identities."""
    counts = {name: int(value) for name, value in values.items()
              if name.startswith(('pairs_', 'picks_'))}
    by_kind = {outcome: sum(count for name, count in counts.items()
                            if name.startswith(f'pairs_{outcome}_'))
               for outcome in ('rejected', 'dropped')}
    pairs_add_up = (counts.get('pairs_received', 0) == sum(
        counts.get(f'pairs_{name}', 0) for name in PAIR_OUTCOMES)
        and by_kind['rejected'] == counts.get('pairs_rejected', 0)
        and by_kind['dropped'] == counts.get('pairs_dropped', 0))
    picks_add_up = counts.get('picks_received', 0) == sum(
        counts.get(f'picks_{name}', 0) for name in PICK_OUTCOMES)
    return counts, pairs_add_up, picks_add_up


def _report(recorder, sent, sent_at, invalid, rss, started, alive, exit_code, answer,
            log_path):
    geometry = PlannerConfig().geometry
    valid_ids = {pair_id for pair_id, (_, outcome) in sent.items()
                 if outcome == 'sent' and pair_id not in invalid}
    released, mispaired, invalid_trajectories = check_trajectories(
        recorder.trajectories, valid_ids, geometry)
    send_to_trajectory = [arrival - sent_at[pair_id] for pair_id, arrival in released]
    released = [pair_id for pair_id, _ in released]
    kinds, pairs_with_status, queue_lengths = {}, set(), []
    plan_times, plan_latency, publish_latency = [], [], []
    counters, all_read_at = None, None
    expected_pairs = sum(outcome == 'sent' for _, outcome in sent.values())
    for arrival, status in recorder.statuses:
        values = _values(status)
        kind = values.get('kind', status.message if status.message in (
            'planned', 'released') else 'other')
        kinds[kind] = kinds.get(kind, 0) + 1
        pairs_with_status.update(status_pairs(status, values))
        if 'queue_length' in values:
            queue_lengths.append(int(values['queue_length']))
        if 'pairs_received' in values:
            received = int(values['pairs_received'])
            if counters is None or received >= int(counters['pairs_received']):
                counters = values
            if all_read_at is None and received >= expected_pairs - 1:  # all but the probe
                all_read_at = arrival - started
        if status.message == 'planned':
            plan_times.append(float(values['plan_time']))
            plan_latency.append(float(values['receive_to_plan_latency']))
        elif status.message == 'released':
            publish_latency.append(float(values['receive_to_publish_latency']))
    counts, pairs_add_up, picks_add_up = node_ledger(counters or {})
    sender = sender_ledger(sent)
    invalid_rejections = expected_rejections(sent, invalid)
    without_status = sorted(set(range(1, counts.get('pairs_received', 0) + 1))
                            - pairs_with_status)
    rss_values = [value for _, value in rss if value is not None]

    def ms(values):
        return {'p50': _ms(percentile(values, 0.5)), 'p99': _ms(percentile(values, 0.99)),
                'max': _ms(max(values) if values else None), 'n': len(values)}

    report = {
        'sender': sender, 'invalid_sent': sum(
            sent[pair_id][1] == 'sent' for pair_id in invalid),
        'node': counts,
        # Sent = refused at the sender + received by the node, for both kinds of message.
        'pairs_lost_in_transport': sender['pairs_sent'] - counts.get('pairs_received', 0),
        'picks_lost_in_transport': sender['picks_sent'] - counts.get('picks_received', 0),
        'pairs_add_up': pairs_add_up, 'picks_add_up': picks_add_up,
        # The invalid pairs sent, by the kind the node must reject them as, and what it did.
        'invalid_rejections': {kind: {'sent': count,
                                      'rejected': counts.get(f'pairs_rejected_{kind}', 0)}
                               for kind, count in invalid_rejections.items()},
        'pairs_without_status': len(without_status),
        'pairs_without_status_first': without_status[:10],
        'node_read_all_pairs_at_s': None if all_read_at is None else round(all_read_at, 1),
        'status_kinds': kinds, 'statuses_recorded': len(recorder.statuses),
        'trajectories': len(recorder.trajectories), 'trajectory_pairs': len(released),
        'duplicate_trajectories': len(released) - len(set(released)),
        'mispaired': len(mispaired), 'mispaired_first': mispaired[:5],
        'invalid_trajectories': len(invalid_trajectories),
        'max_queue_length': max(queue_lengths) if queue_lengths else None,
        'alive_after': alive, 'exit_code': exit_code,
        'answer_after_flood_s': None if answer is None else round(answer, 3),
        'rss_kib': {'start': rss_values[0] if rss_values else None,
                    'end': rss_values[-1] if rss_values else None,
                    'max': max(rss_values) if rss_values else None,
                    'samples': len(rss_values),
                    'per_minute': _per_minute(rss)},
        'plan_time_ms': ms(plan_times),
        'receive_to_plan_latency_ms': ms(plan_latency),
        'receive_to_publish_latency_ms': ms(publish_latency),
        'send_to_trajectory_ms': ms(send_to_trajectory),
        'node_log': log_path,
    }
    report['ok'] = bool(alive and answer is not None and not mispaired
                        and not invalid_trajectories and pairs_add_up and picks_add_up
                        and all(count['sent'] == count['rejected']
                                for count in report['invalid_rejections'].values())
                        and not without_status and report['pairs_lost_in_transport'] == 0
                        and report['picks_lost_in_transport'] == 0)
    return report


def _per_minute(rss):
    """Return the first RSS sample of each minute of the run [KiB]."""
    minutes = {}
    for elapsed, value in rss:
        if value is not None:
            minutes.setdefault(int(elapsed // 60.0), value)
    return [minutes[minute] for minute in sorted(minutes)]


def _ms(seconds):
    return None if seconds is None else round(1e3 * seconds, 1)


def main():
    """Run the flood from the command line; print the report as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--rate', type=float, default=1000.0, help='pairs per second')
    parser.add_argument('--seconds', type=float, default=60.0)
    parser.add_argument('--invalid', type=float, default=0.02,
                        help='share of invalid pairs (NaN place or wrong frame)')
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--drain-timeout', type=float, default=DRAIN_TIMEOUT,
                        help='how long the node may take to read and plan what it holds [s]')
    parser.add_argument('--stream', choices=STREAMS, default='mixed',
                        help='pick_place messages, pick_pose + place_pose, or both')
    parser.add_argument('--log-dir', help="where the node's log goes (default: a temp dir)")
    options = parser.parse_args()
    report = run(options.rate, options.seconds, options.seed, invalid_share=options.invalid,
                 log_dir=options.log_dir, out=sys.stderr, stream=options.stream,
                 drain_timeout=options.drain_timeout)
    print(json.dumps(report, indent=1))
    return 0 if report['ok'] else 1


if __name__ == '__main__':
    sys.exit(main())
