"""Optional dependencies ("extras"): which modules each needs, and a check that names the
``pip install`` line before any work is done."""

from __future__ import annotations

import importlib
import importlib.util
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


def require(*extras: str, purpose: str) -> None:
    """Raises :class:`MissingExtraError` naming every missing extra and the install line.

    Args:
        extras: extra names (``render``, ``ros``, ``eval``, ``train``, ``ray``).
        purpose: what needs them, for the message (``"boids run --video"``).
    """
    lacking = {e: m for e in dict.fromkeys(extras) if (m := missing(e))}
    if not lacking:
        return
    names = ",".join(lacking)
    detail = "; ".join(f"{e}: {', '.join(m)}" for e, m in lacking.items())
    hint = f" ({TORCH_HINT})" if "train" in lacking else ""
    raise MissingExtraError(f"{purpose} needs the {names} extra ({detail} not installed): "
                            f"pip install 'boids-env[{names}]'{hint}")


def import_extra(module: str, message: str) -> ModuleType:
    """``module``, imported where it is first needed; where it is missing, an ``ImportError``
    with ``message`` (what needs it and the ``pip install`` line), the cause chained."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(message) from exc
