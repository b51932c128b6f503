"""The study's ROS 1 graph, for real: the pymunk world as a simulator node (``boids ros sim``,
in place of Stage) and any policy as the study's ``reynolds_controller`` node (``boids ros
controller``), on the original topics ``/robot_k/odom`` and ``/robot_k/cmd_vel``.

Importing this package needs no ROS: ``rospy`` and the message packages are imported when a
node starts, through :func:`boids_env.eval.ros.rospy_path.import_rospy`, which finds Debian's
or a ROS Noetic install's Python packages and names the packages to install when they are
missing. The bag reader of :mod:`~boids_env.eval.ros.bags` is usable and tested without ROS,
as is the graph's transport-free part, :mod:`boids_env.eval.graph` (its protocol included).
"""
