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

"""The test set-up itself: which ROS domain a session uses, and the per-test timeout."""

import configparser
import os
from pathlib import Path
import subprocess
import sys

import pytest

TEST_DIR = Path(__file__).resolve().parent


def _domain_base(**environment):
    """Return the DOMAIN_ID_BASE conftest.py picks in a fresh process with ``environment``."""
    env = {key: value for key, value in os.environ.items()
           if key not in ('ROS_DOMAIN_ID', 'ELLIPATH_TEST_DOMAIN_ID')}
    env.update(environment)
    result = subprocess.run(
        [sys.executable, '-c', 'import conftest, os; '
         'print(conftest.DOMAIN_ID_BASE, os.environ["ROS_DOMAIN_ID"])'],
        cwd=TEST_DIR, env=env, capture_output=True, text=True, timeout=60, check=True)
    return result.stdout.split()


@pytest.mark.parametrize('environment, expected', [
    ({'ROS_DOMAIN_ID': '17', 'ELLIPATH_TEST_DOMAIN_ID': '30'}, '17'),  # the caller's wins
    ({'ELLIPATH_TEST_DOMAIN_ID': '30'}, '30'),
    ({'ROS_DOMAIN_ID': '', 'ELLIPATH_TEST_DOMAIN_ID': '31'}, '31'),  # empty counts as unset
    ({}, '46'),
])
def test_the_domain_base_respects_the_caller(environment, expected):
    assert _domain_base(**environment) == [expected, expected]


def test_every_test_has_a_timeout():
    parser = configparser.ConfigParser()
    parser.read(TEST_DIR.parent / 'pytest.ini')
    assert 0 < float(parser['pytest']['timeout']) <= 300
    assert parser['pytest']['timeout_method'] == 'thread'
