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
    arguments = (stamp, name, '/ns/ellipath_node', level, message, values)
    expected = diagnostic_array(*arguments)
    serialized = serialized_diagnostic_array(*arguments)
    assert deserialize_message(serialized, DiagnosticArray) == expected
