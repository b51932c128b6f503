"""The study's live graph without a transport: what the simulator node publishes and when,
what the controller node computes, the protocol both speak and their messages, once.

:mod:`~boids_env.eval.graph.sim` steps the world, waits for the graph before tick 0 and hands
every tick to a :class:`~boids_env.eval.graph.sim.SimTransport`;
:mod:`~boids_env.eval.graph.controller` assembles ticks of odometry, runs the answering loop
and turns each tick into the followers' commands over a
:class:`~boids_env.eval.graph.controller.ControllerTransport`;
:mod:`~boids_env.eval.graph.messages` makes a tick's messages with the one builder
(:class:`boids_env.rosmsgs.Messages`); :mod:`~boids_env.eval.graph.protocol` is what the
nodes agree on (topics, stamps, episodes, lockstep). The transports are thin: ROS 1
(:mod:`boids_env.eval.ros`, rospy) and ROS 2 over Zenoh (:mod:`boids_env.eval.ros2`,
rmw_zenoh's conventions, no ROS install) say only what their middleware knows (who publishes,
who receives, how to publish); the tests run both nodes in one process over a loopback.

Nothing here imports a middleware.
"""
