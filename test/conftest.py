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
Shared test set-up: keep DDS on this host and give each ROS test module its own domain.

The environment is set here, at import, before any test module imports or initialises
rclpy. A module that uses ROS sets ``ROS_DOMAIN_OFFSET`` (0, 1, 2, ...); its domain id is a
base plus that offset. The base is the caller's ``ROS_DOMAIN_ID`` if set, else
``ELLIPATH_TEST_DOMAIN_ID``, else 46, so two test sessions on one host are kept apart by
giving them different ``ROS_DOMAIN_ID`` (or ``ELLIPATH_TEST_DOMAIN_ID``) values, e.g.
``ROS_DOMAIN_ID=40 make test`` uses domains 40, 41, ...
"""

import os

import pytest

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
DOMAIN_ID_BASE = int(os.environ.get('ROS_DOMAIN_ID')
                     or os.environ.get('ELLIPATH_TEST_DOMAIN_ID') or '46')
os.environ['ROS_DOMAIN_ID'] = str(DOMAIN_ID_BASE)


@pytest.fixture(scope='module')
def ros_domain_id(request):
    """Return the ROS domain id of the requesting test module."""
    return DOMAIN_ID_BASE + getattr(request.module, 'ROS_DOMAIN_OFFSET', 0)


@pytest.fixture(scope='module')
def ros_env(ros_domain_id):
    """Return the environment for a ROS subprocess of the requesting test module."""
    env = dict(os.environ)
    env.update(ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', ROS_DOMAIN_ID=str(ros_domain_id),
               PYTHONUNBUFFERED='1')
    return env


@pytest.fixture(scope='module')
def ros_context(ros_domain_id):
    """Yield an initialised rclpy context of its own (no signal handlers), on the domain."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.fixture(scope='module')
def monkeypatch_module():
    """Yield a monkeypatch that lasts for the module."""
    with pytest.MonkeyPatch.context() as patch:
        yield patch
