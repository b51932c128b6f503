"""The study's live graph without a transport: what the simulator node publishes and when,
what the controller node computes, and the lockstep protocol, once.

:mod:`~boids_env.eval.graph.sim` steps the world and hands every tick to a *transport*;
:mod:`~boids_env.eval.graph.controller` turns a tick of odometry into the followers'
commands. The transports are thin: ROS 1 (:mod:`boids_env.eval.ros`, rospy) and ROS 2 over
Zenoh (:mod:`boids_env.eval.ros2`, rmw_zenoh's conventions, no ROS install). The protocol both
speak (topics, stamps, episodes, lockstep) is :mod:`boids_env.eval.graph.protocol`.

Nothing here imports a middleware.
"""
