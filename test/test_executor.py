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


"""InlineGroupExecutor: which thread runs which callback, and that callbacks' errors surface."""

import threading
import time

from ellipath_ros.executor import InlineGroupExecutor
import pytest

ROS_DOMAIN_OFFSET = 3  # see conftest.py; only timers, nothing on the network
SPIN_TIMEOUT = 10.0  # s, for the callbacks to have run


class _Failure(Exception):
    """Raised by a callback under test."""


@pytest.fixture
def node(ros_context):
    """Yield a node of the module's context, destroyed after the test."""
    from rclpy.node import Node

    node = Node('executor_test', context=ros_context)
    yield node
    node.destroy_node()


@pytest.fixture
def make_executor(ros_context):
    """Yield a factory of InlineGroupExecutors for the context, all shut down after the test."""
    executors = []

    def make(groups, num_threads=2):
        executor = InlineGroupExecutor(groups, num_threads, context=ros_context)
        executors.append(executor)
        return executor

    yield make
    for executor in executors:
        executor.shutdown()


def _spin_until(executor, condition):
    deadline = time.monotonic() + SPIN_TIMEOUT
    while not condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return condition()


def _once_timer(node, group, callback):
    """Create a timer of ``group`` that calls ``callback`` once (then cancels itself)."""
    timer = None

    def fire():
        timer.cancel()
        callback()

    timer = node.create_timer(0.001, fire, callback_group=group)
    return timer


def test_inline_group_runs_in_the_spinning_thread_the_others_in_the_pool(node, make_executor):
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

    inline, other = MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup()
    threads = {}
    _once_timer(node, inline, lambda: threads.setdefault('inline', threading.get_ident()))
    _once_timer(node, other, lambda: threads.setdefault('other', threading.get_ident()))
    executor = make_executor([inline])
    executor.add_node(node)
    assert _spin_until(executor, lambda: len(threads) == 2)
    assert threads['inline'] == threading.get_ident()
    assert threads['other'] != threading.get_ident()


def test_a_long_pool_callback_does_not_hold_up_the_inline_group(node, make_executor):
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

    inline, other = MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup()
    release = threading.Event()
    inline_calls = []
    _once_timer(node, other, lambda: release.wait(SPIN_TIMEOUT))
    node.create_timer(0.001, lambda: inline_calls.append(release.is_set()),
                      callback_group=inline)
    executor = make_executor([inline])
    executor.add_node(node)
    # The pool callback blocks until released: the inline timer runs meanwhile, repeatedly.
    assert _spin_until(executor, lambda: len(inline_calls) >= 3)
    assert not any(inline_calls)
    release.set()


def test_an_inline_callbacks_error_is_raised_from_spin_once(node, make_executor):
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

    inline = MutuallyExclusiveCallbackGroup()

    def fail():
        raise _Failure('inline')

    _once_timer(node, inline, fail)
    executor = make_executor([inline])
    executor.add_node(node)
    with pytest.raises(_Failure, match='inline'):
        _spin_until(executor, lambda: False)


def test_a_pool_callbacks_error_is_raised_from_a_later_spin_once(node, make_executor):
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

    inline, other = MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup()

    def fail():
        raise _Failure('pool')

    _once_timer(node, other, fail)
    # A steady inline timer, so that spin_once keeps returning after the pool callback failed.
    node.create_timer(0.001, lambda: None, callback_group=inline)
    executor = make_executor([inline])
    executor.add_node(node)
    with pytest.raises(_Failure, match='pool'):
        _spin_until(executor, lambda: False)


def test_spin_until_future_complete_returns_when_a_pool_task_is_done(node, make_executor):
    executor = make_executor([])
    executor.add_node(node)
    future = executor.create_task(lambda: 'done')
    executor.spin_until_future_complete(future, timeout_sec=SPIN_TIMEOUT)
    assert future.result() == 'done'
