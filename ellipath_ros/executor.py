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
The node's executor: some callback groups served in the spinning thread, the others in a pool.

rclpy's ``MultiThreadedExecutor`` hands every ready callback to a pool thread. For the node's
intake that hand-over was the largest part of its own delay between a place pose arriving and
its plan starting: the spinning thread wakes a pool thread and both then take turns at the GIL
(the spinning thread goes on rebuilding its wait set). Measured end to end (``ellipath bench``'s
client and the node on this host, 2x2 interleaved runs of 70 pairs, load 0.1-0.3), from the
pose's arrival in the node's DDS reader to its callback: p50/p90/p99 0.81/4.36/9.53 ms with
the hand-over, 0.41/0.54/0.78 ms without. :class:`InlineGroupExecutor` runs the callbacks of
the groups it is given in the spinning thread itself, right after its wait returns, and hands
the others to its pool, so that a long callback of another group (a parameter change,
clear_queue) never holds up intake, and intake never waits for a pool thread.
"""

from concurrent.futures import ThreadPoolExecutor

from rclpy.executors import ConditionReachedException
from rclpy.executors import Executor
from rclpy.executors import ExternalShutdownException
from rclpy.executors import ShutdownException
from rclpy.executors import TimeoutException

__all__ = ['InlineGroupExecutor']


class InlineGroupExecutor(Executor):
    """
    Run the callbacks of ``inline_groups`` in the spinning thread, the others in a pool.

    Parameters
    ----------
    inline_groups : iterable of rclpy.callback_groups.CallbackGroup
        Groups whose callbacks run in the thread that calls :meth:`spin_once`. Their callbacks
        must be short: nothing else is dispatched while one runs.
    num_threads : int
        Pool threads for the callbacks of every other group (and for tasks).
    context : rclpy.context.Context, optional
        The executor's context.

    Notes
    -----
    An exception of a callback is raised from :meth:`spin_once`, as rclpy's executors do: at
    once for an inline callback, at a later call for a pool callback (when it is seen done).

    """

    def __init__(self, inline_groups, num_threads, *, context=None):
        super().__init__(context=context)
        self._inline_groups = tuple(inline_groups)
        self._pool = ThreadPoolExecutor(num_threads)
        # The pool's tasks (rclpy Tasks: they hold a callback's exception, which the pool's
        # own futures never see) until seen done.
        self._pool_tasks = []

    def _spin_once_impl(self, timeout_sec=None, wait_condition=lambda: False):
        try:
            handler, entity, _ = self.wait_for_ready_callbacks(timeout_sec, None, wait_condition)
        except (ConditionReachedException, ExternalShutdownException, ShutdownException,
                TimeoutException):
            return
        if entity is not None and any(entity.callback_group is group
                                      for group in self._inline_groups):
            handler()
            handler.result()  # raises the callback's exception
        else:
            self._pool.submit(handler)
            self._pool_tasks.append(handler)
        finished = [task for task in self._pool_tasks if task.done()]
        for task in finished:
            self._pool_tasks.remove(task)
        for task in finished:
            task.result()

    def spin_once(self, timeout_sec=None):
        """Wait up to ``timeout_sec`` for one ready callback, then run or dispatch it."""
        self._spin_once_impl(timeout_sec)

    def spin_once_until_future_complete(self, future, timeout_sec=None):
        """As :meth:`spin_once`, returning as soon as ``future`` is done."""
        future.add_done_callback(lambda _: self.wake())
        self._spin_once_impl(timeout_sec, future.done)

    def shutdown(self, timeout_sec=None):
        """Stop executing callbacks and wait for them as rclpy does; the pool takes no more."""
        done = super().shutdown(timeout_sec)
        self._pool.shutdown(wait=False)
        return done
