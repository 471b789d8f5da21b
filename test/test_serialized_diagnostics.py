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

"""The serialized /diagnostics status the node publishes is rclpy's DiagnosticArray message."""

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from diagnostic_msgs.msg import KeyValue
from ellipath_ros.conversions import serialized_diagnostic_array
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from std_msgs.msg import Header

# Strings of every length modulo 4 (CDR pads before each string's length), numbers as the
# node formats them, text that is not ASCII, and no values at all.
VALUES = (
    {},
    {'pair': 12},
    {'plan_time': 0.123456789012, 'topic': 'pick_place', 'x': np.float64(1.5), 'ok': True,
     'queue': 3, 'abc': 'de', 'reason': 'caf\u00e9 \u2192 d\u00e9j\u00e0'},
)


def diagnostic_array(stamp, statuses):
    """Build the reference message with rclpy's classes (floats with 9 significant digits)."""
    def text(value):
        return f'{float(value):.9g}' if isinstance(value, (float, np.floating)) else str(value)

    return DiagnosticArray(header=Header(stamp=stamp), status=[
        DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                         values=[KeyValue(key=str(key), value=text(value))
                                 for key, value in values.items()])
        for name, hardware_id, level, message, values in statuses])


@pytest.mark.parametrize('level', (DiagnosticStatus.OK, DiagnosticStatus.WARN,
                                   DiagnosticStatus.ERROR, DiagnosticStatus.STALE))
@pytest.mark.parametrize('values', VALUES)
@pytest.mark.parametrize('name, message', (('ellipath', 'planned'), ('a', 'released'),
                                           ('ab', ''), ('abc', 'x' * 257)))
def test_serialized_status_is_the_message(level, values, name, message):
    stamp = Time(sec=1_764_300_000, nanosec=999_999_999)
    status = (name, '/ns/ellipath_node', level, message, values)
    expected = diagnostic_array(stamp, [status])
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
        expected = diagnostic_array(stamp, chosen)
        assert deserialize_message(serialized_diagnostic_array(stamp, chosen),
                                   DiagnosticArray) == expected


def test_values_are_written_with_nine_significant_digits_and_as_text():
    stamp = Time(sec=1, nanosec=2)
    status = ('ellipath', '/ellipath_node', DiagnosticStatus.OK, 'planned',
              {'duration': 0.123456789012, 'count': 80, 'policy': 'paper'})
    values = deserialize_message(serialized_diagnostic_array(stamp, [status]),
                                 DiagnosticArray).status[0].values
    assert [(item.key, item.value) for item in values] == [
        ('duration', '0.123456789'), ('count', '80'), ('policy', 'paper')]
