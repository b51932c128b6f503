"""The physical world: everything that exists and moves, independent of RL.

- :mod:`~boids_env.world.space`: the pymunk space (robots, walls, contacts) and ``Snapshot``
- :mod:`~boids_env.world.leader`: the scripted leader paths
- :mod:`~boids_env.world.layout` / :mod:`~boids_env.world.scenario`: start grids, seeding and
  the episode's length
- :mod:`~boids_env.world.realism`: the opt-in ROS/Stage realism

The modules are imported by name (``from boids_env.world.space import World``); this package
imports nothing itself, so the config can import the layout without a cycle.
"""
