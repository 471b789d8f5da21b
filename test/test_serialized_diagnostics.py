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

"""The serialized /diagnostics status the node publishes is diagnostic_array's message."""

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from ellipath_ros.conversions import diagnostic_array
from ellipath_ros.conversions import diagnostic_status
from ellipath_ros.conversions import serialized_diagnostic_array
import numpy as np
import pytest
from rclpy.serialization import deserialize_message

# Strings of every length modulo 4 (CDR pads before each string's length), numbers as the
# node formats them, text that is not ASCII, and no values at all.
VALUES = (
    {},
    {'pair': 12},
    {'plan_time': 0.123456789012, 'topic': 'pick_place', 'x': np.float64(1.5), 'ok': True,
     'queue': 3, 'abc': 'de', 'reason': 'caf\u00e9 \u2192 d\u00e9j\u00e0'},
)


@pytest.mark.parametrize('level', (DiagnosticStatus.OK, DiagnosticStatus.WARN,
                                   DiagnosticStatus.ERROR, DiagnosticStatus.STALE))
@pytest.mark.parametrize('values', VALUES)
@pytest.mark.parametrize('name, message', (('ellipath', 'planned'), ('a', 'released'),
                                           ('ab', ''), ('abc', 'x' * 257)))
def test_serialized_status_is_the_message(level, values, name, message):
    stamp = Time(sec=1_764_300_000, nanosec=999_999_999)
    status = (name, '/ns/ellipath_node', level, message, values)
    expected = diagnostic_array(stamp, [diagnostic_status(*status)])
    serialized = serialized_diagnostic_array(stamp, [status])
    assert deserialize_message(serialized, DiagnosticArray) == expected


def test_serialized_statuses_are_the_message():
    """Several statuses in one array (the node's batched intake statuses), and none."""
    stamp = Time(sec=3, nanosec=7)
    statuses = [(f'ellipath{index}', '/ns/ellipath_node', level, 'x' * index, values)
                for index, (level, values) in enumerate(zip(
                    (DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR),
                    VALUES))]
    for chosen in (statuses, statuses[:1], []):
        expected = diagnostic_array(stamp, [diagnostic_status(*status) for status in chosen])
        assert deserialize_message(serialized_diagnostic_array(stamp, chosen),
                                   DiagnosticArray) == expected
