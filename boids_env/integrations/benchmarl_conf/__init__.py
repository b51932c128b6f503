"""BenchMARL's config layout for this package's task (``task/boids/leader_following.yaml``):
read by :meth:`BoidsTask.get_from_yaml <boids_env.integrations.benchmarl.BoidsTask.get_from_yaml>`
and put on Hydra's search path by :mod:`boids_env.integrations.benchmarl_run`."""
