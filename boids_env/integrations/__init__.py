"""Glue for third-party MARL libraries, one module per library, each imported only when asked
(the core never imports them):

- :mod:`boids_env.integrations.supersuit`: SuperSuit's vector env for Stable-Baselines3 with
  one episode per copy, seeded the SB3 way (``pip install -e '.[clients,train]'``);
- :mod:`boids_env.integrations.rllib`: the env registered for RLlib (``pip install -e '.[rllib]'``);
- :mod:`boids_env.integrations.benchmarl`: a BenchMARL task (``pip install -e '.[benchmarl]'``).

The Gymnasium id ``boids_env/SingleFollower-v0`` needs no glue: ``import boids_env`` registers it.
"""


def missing_extra(module: str, extra: str, exc: ImportError) -> ImportError:
    """The error a glue module raises when its library is not installed: which extra brings it."""
    return ImportError(f"boids_env.integrations.{module} needs {exc.name or 'its library'}: "
                       f"pip install -e '.[{extra}]' (in the boids-env clone)")
