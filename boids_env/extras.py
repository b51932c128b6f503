"""Optional dependencies ("extras"): which modules each needs, and a check that names the
``pip install`` line before any work is done."""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Mapping
from types import ModuleType

EXTRAS: dict[str, tuple[str, ...]] = {
    "render": ("pygame", "imageio", "tqdm"),
    "video": ("pygame", "imageio", "imageio_ffmpeg", "tqdm"),
    "ros": ("rosbags",),
    "ros2": ("zenoh", "rosbags"),
    "live": ("foxglove",),
    "eval": ("statsmodels", "matplotlib", "tqdm", "tabulate", "markdown"),
    "train": ("stable_baselines3", "torch", "tensorboard", "tqdm", "rich"),
    "ray": ("ray",),
    "people": ("jupedsim", "shapely"),
}
"""The import names each extra of ``boids-env`` provides."""

TORCH_HINT = ("torch is not pinned by the extra: on a machine without a GPU install the CPU "
              "build first (pip install torch --index-url https://download.pytorch.org/whl/cpu)")


class MissingExtraError(ImportError):
    """An optional dependency is not installed; the message says which extra to install."""


def missing(extra: str) -> list[str]:
    """The modules of ``extra`` that cannot be imported here."""
    if extra not in EXTRAS:
        raise ValueError(f"extra must be one of {sorted(EXTRAS)}, got {extra!r}")
    return [m for m in EXTRAS[extra] if importlib.util.find_spec(m) is None]


def install_line(names: str) -> str:
    """The command that installs the extras ``names`` (``"people"``, ``"render,eval"``): from
    the clone, as the package is not published."""
    return f"pip install -e '.[{names}]' (in the boids-env clone)"


def require(*extras: str, purpose: str, flags: Mapping[str, str] | None = None) -> None:
    """Raises :class:`MissingExtraError` naming every missing extra and the install line.

    Args:
        extras: extra names (``render``, ``ros``, ``eval``, ``train``, ``ray``).
        purpose: what needs them, for the message (``"boids run --video"``).
        flags: the options that need each extra (``{"people": "--crowd 10"}``), added to
            ``purpose`` for the missing extras only, so that the message names what needs
            what is missing (not ``--video`` for the crowd's extra).
    """
    lacking = {e: m for e in dict.fromkeys(extras) if (m := missing(e))}
    if not lacking:
        return
    names = ",".join(lacking)
    detail = "; ".join(f"{e}: {', '.join(m)}" for e, m in lacking.items())
    hint = f" ({TORCH_HINT})" if "train" in lacking else ""
    given = flags or {}
    wanted = " ".join(dict.fromkeys(given[e] for e in lacking if e in given))
    raise MissingExtraError(f"{purpose}{' ' * bool(wanted)}{wanted} needs the {names} extra "
                            f"({detail} not installed): {install_line(names)}{hint}")


def import_extra(module: str, message: str) -> ModuleType:
    """``module``, imported where it is first needed; where it is missing, an ``ImportError``
    with ``message`` (what needs it and the ``pip install`` line), the cause chained."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(message) from exc
