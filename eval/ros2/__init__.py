"""The study's graph as ROS 2 nodes over Zenoh, rmw_zenoh's way, with no ROS install
(``boids ros2 sim|controller``, the ``ros2`` extra): :mod:`~boids_env.eval.ros2.wire`
(rmw_zenoh's conventions, pure), :mod:`~boids_env.eval.ros2.node` (a node on a Zenoh session),
and the simulator's and controller's transports (:mod:`~boids_env.eval.ros2.sim`,
:mod:`~boids_env.eval.ros2.controller`) under :mod:`boids_env.eval.graph`'s logic.

Importing this package needs no Zenoh: it is imported when a node starts.
"""
