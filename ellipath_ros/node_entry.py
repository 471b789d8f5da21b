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
The ``ellipath_node`` command: takes SIGINT and SIGTERM before the node's imports.

Importing ``ellipath_ros.node`` (rclpy, NumPy, numba and the planner's compiled loops) takes
one to several seconds, and ``node.main`` installs its signal handlers only after that. A
signal in that window got Python's defaults: a KeyboardInterrupt traceback for SIGINT, or,
in a process that inherited SIGINT ignored (started with ``&`` by a script, ``nohup``),
nothing at all, so the node started anyway and a second signal was needed. Here a signal in
that window is only recorded, and ``node.main`` stops as soon as its own handlers are in
place: exit status 0, no traceback, at any moment after the process starts.

It also sets glibc's malloc policy before those imports (:mod:`ellipath_ros.malloc_policy`):
importing rclpy starts threads that allocate, and each would otherwise make an arena of its
own that stays. ``python -m ellipath_ros.node_entry`` runs the same as the command.
"""

import signal
import sys

from ellipath_ros.malloc_policy import set_malloc_policy


def main(args=None):
    """
    Run ``ellipath_node`` (``node.main``); a SIGINT or SIGTERM during its imports stops it.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments (``--ros-args ...``); ``sys.argv`` if None.

    """
    early_signals = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda signum, frame: early_signals.append(signum))
    set_malloc_policy()  # before rclpy's threads exist
    from ellipath_ros import node  # after the handlers, on purpose (see above)
    return node.main(args, early_signals=early_signals)


if __name__ == '__main__':
    sys.exit(main())
