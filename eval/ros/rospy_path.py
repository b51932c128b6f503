"""Reaching ``rospy`` from a virtualenv without breaking anything for users without ROS.

ROS 1 is not on PyPI: ``rospy`` and the message packages come from Debian/Ubuntu
(``apt-get install ros-core python3-rospy …``, into ``/usr/lib/python3/dist-packages``) or
from a ROS Noetic install (``/opt/ros/noetic/lib/python3/dist-packages``, put on
``PYTHONPATH`` by ``source /opt/ros/noetic/setup.bash``). A virtualenv does not see either.
:func:`import_rospy` imports ``rospy`` as it is if it can; only when it cannot does it
*append* the first of those folders that holds ``rospy`` to ``sys.path``. Appending (never
prepending) keeps every package the virtualenv has in front: the system folder only supplies
what the virtualenv lacks (rospy, genpy, rospkg, the messages, …), so the env's numpy, yaml or
cffi are never replaced. Nothing here runs on ``import boids_env``.
"""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path
from types import ModuleType

SEARCH_PATH_VARIABLE = "BOIDS_ROS_PYTHONPATH"
"""Environment variable: folders (``os.pathsep``-separated) to look for ``rospy`` in, before
the default ones."""
DEFAULT_FOLDERS = ("/opt/ros/noetic/lib/python3/dist-packages", "/usr/lib/python3/dist-packages")
"""Where ROS Noetic and Debian/Ubuntu install ROS 1's Python packages."""
APT_PACKAGES = ("ros-core", "python3-rospy", "python3-nav-msgs", "python3-geometry-msgs",
                "python3-visualization-msgs", "python3-tf2-msgs", "python3-rosgraph-msgs",
                "python3-dynamic-reconfigure", "python3-rosbag")
"""The Debian/Ubuntu packages the ROS nodes need (``ros-core`` brings ``roscore``,
``rostopic`` and the ``rosbag`` tool)."""
MESSAGE_MODULES = ("nav_msgs.msg", "geometry_msgs.msg", "visualization_msgs.msg",
                   "tf2_msgs.msg", "rosgraph_msgs.msg", "std_msgs.msg")
"""The message packages the nodes publish and subscribe."""

INSTALL_HINT = (f"sudo apt-get install {' '.join(APT_PACKAGES)} (Debian 12 / Ubuntu), or a ROS "
                f"Noetic install (source /opt/ros/noetic/setup.bash)")


class MissingRosError(ImportError):
    """ROS 1's Python packages cannot be imported; the message says what to install."""


def candidate_folders() -> list[Path]:
    """Folders that may hold ROS 1's Python packages, in the order they are tried."""
    extra = os.environ.get(SEARCH_PATH_VARIABLE, "")
    return [Path(p) for p in [*extra.split(os.pathsep), *DEFAULT_FOLDERS] if p]


def import_rospy() -> ModuleType:
    """``rospy``, with the message packages checked; raises :class:`MissingRosError` naming
    the packages to install when they are not there.

    The system folder is appended to ``sys.path`` only if ``rospy`` is not importable as it is.
    """
    try:
        import rospy
    except ImportError:
        folder = next((f for f in candidate_folders() if (f / "rospy").is_dir()), None)
        if folder is None:
            raise MissingRosError(
                f"the ROS nodes need ROS 1's rospy, not found on sys.path nor in "
                f"{', '.join(str(f) for f in candidate_folders())}: {INSTALL_HINT}") from None
        if str(folder) not in sys.path:
            sys.path.append(str(folder))
        try:
            import rospy
        except ImportError as exc:
            raise MissingRosError(
                f"rospy in {folder} cannot be imported by Python "
                f"{sys.version_info.major}.{sys.version_info.minor} ({exc}); ROS 1's packages "
                f"are built for the system's python3, so use a virtualenv made from it: "
                f"{INSTALL_HINT}") from exc
    missing = []
    for name in MESSAGE_MODULES:
        try:
            importlib.import_module(name)
        except ImportError:
            missing.append(name.split(".")[0])
    if missing:
        raise MissingRosError(f"ROS message packages {missing} are missing: {INSTALL_HINT}")
    return rospy

