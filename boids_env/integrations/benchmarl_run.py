"""BenchMARL's command line with the boids task: ``python -m boids_env.integrations.benchmarl_run
algorithm=mappo task=boids/leader_following [+task.robots=5 ...] [experiment.max_n_iters=...]``.

It is BenchMARL's own ``benchmarl.run`` (its Hydra app, its ``conf`` folder, its overrides),
after two things BenchMARL cannot do for a task shipped outside it: importing
:mod:`boids_env.integrations.benchmarl` (which registers ``boids/leader_following`` in its
``task_config_registry``) and adding this package's config folder to Hydra's search path
(``hydra.searchpath``, Hydra's own hook for configs of another package). BenchMARL warns
that the task has no ``TaskConfig`` dataclass: the env checks its fields itself, when the
task's env function is made.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

SEARCH_PATH = "pkg://boids_env.integrations.benchmarl_conf"
"""Where Hydra finds ``task/boids/*.yaml``."""


def argv_with_search_path(argv: Sequence[str]) -> list[str]:
    """``argv`` with this package's config folder on Hydra's search path (the user's own
    ``hydra.searchpath=[...]`` keeps its entries, ours added)."""
    out, added = [], False
    for arg in argv:
        if arg.startswith("hydra.searchpath=[") and arg.endswith("]"):
            inner = arg[len("hydra.searchpath=["):-1]
            arg = f"hydra.searchpath=[{inner + ',' if inner else ''}{SEARCH_PATH}]"
            added = True
        out.append(arg)
    return out if added else [*out, f"hydra.searchpath=[{SEARCH_PATH}]"]


def main() -> None:
    """Runs BenchMARL's Hydra app on ``sys.argv`` with the task registered."""
    from benchmarl.run import hydra_experiment

    import boids_env.integrations.benchmarl  # noqa: F401  (registers the task)

    sys.argv = [sys.argv[0], *argv_with_search_path(sys.argv[1:])]
    hydra_experiment()


if __name__ == "__main__":
    main()
