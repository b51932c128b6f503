"""The Reynolds parameters as a dynamic_reconfigure panel, without catkin.

dynamic_reconfigure normally generates a ``<Name>Config.py`` module from a ``.cfg`` file at
catkin build time; ``dynamic_reconfigure.server.Server`` then only reads that module's
attributes ``config_description`` (the parameter tree), ``defaults``, ``min``, ``max``,
``level`` and ``type``. :func:`config_type` builds exactly those attributes in memory, in the
generator's format (one ``Default`` group, ``double`` parameters), from
:class:`~boids_env.policies.reynolds_params.ReynoldsParams`. So the node serves the standard
services and topics
(``~set_parameters``, ``~parameter_descriptions``, ``~parameter_updates``): ``rosrun
dynamic_reconfigure dynparam set``, rqt_reconfigure and ``dynamic_reconfigure.client`` all work,
and no build step or generated file exists. Pure Python: no ROS import here.
"""

from __future__ import annotations

from dataclasses import asdict, replace
from types import SimpleNamespace
from typing import Any

from boids_env.policies.reynolds_params import TUNABLE, ReynoldsParams, tunable_range


def config_type(params: ReynoldsParams, sensing_horizon: float) -> SimpleNamespace:
    """The in-memory equivalent of a generated ``ReynoldsConfig`` module.

    Args:
        params: the starting values (the defaults the panel shows).
        sensing_horizon: the observations' neighbour radius (m), the horizon's maximum.
    """
    values = asdict(params)
    parameters = []
    for bit, (name, tunable) in enumerate(TUNABLE.items()):
        low, top = tunable_range(name, sensing_horizon)
        text = tunable.text
        parameters.append({
            "name": name, "type": "double", "default": float(values[name]),
            "level": 1 << bit, "description": text, "min": float(low), "max": float(top),
            "srcline": 0, "srcfile": "reconfigure.py", "edit_method": "",
            "ctype": "double", "cconsttype": "const double"})
    description = {
        "name": "Default", "type": "", "state": True, "cstate": "true", "id": 0, "parent": 0,
        "parameters": parameters, "groups": [], "srcline": 0, "srcfile": "reconfigure.py",
        "class": "DEFAULT", "parentclass": "", "parentname": "Default", "field": "default",
        "upper": "DEFAULT", "lower": "groups"}
    level = {p["name"]: p["level"] for p in parameters}
    return SimpleNamespace(
        config_description=description,
        min={p["name"]: p["min"] for p in parameters},
        max={p["name"]: p["max"] for p in parameters},
        defaults={p["name"]: p["default"] for p in parameters},
        level=level, type={p["name"]: "double" for p in parameters},
        all_level=sum(level.values()))


def apply(params: ReynoldsParams, config: dict[str, Any]) -> tuple[ReynoldsParams, str | None]:
    """``params`` with the panel's values of :data:`TUNABLE` (other keys, such as
    dynamic_reconfigure's ``groups``, are ignored); an invalid combination leaves ``params``
    unchanged and returns the error message."""
    changes = {name: float(config[name]) for name in TUNABLE if name in config}
    try:
        return replace(params, **changes), None
    except ValueError as exc:
        return params, str(exc)


def parse_assignments(items: list[str]) -> dict[str, float]:
    """``["leader_weight=1.2", "horizon=0.8"]`` -> ``{"leader_weight": 1.2, "horizon": 0.8}``;
    a ``ValueError`` naming the item for anything else."""
    changes = {}
    for item in items:
        name, eq, text = item.partition("=")
        if not eq or name not in TUNABLE:
            raise ValueError(f"expected name=value with name one of {list(TUNABLE)}, got "
                             f"{item!r}")
        try:
            changes[name] = float(text)
        except ValueError:
            raise ValueError(f"{name} must be a number, got {text!r}") from None
    return changes


def reconfigure_node(node: str, changes: dict[str, float], timeout: float = 10.0
                     ) -> dict[str, float]:
    """Changes ``node``'s parameters through its dynamic_reconfigure services (what
    rqt_reconfigure and ``dynparam`` do; Debian's ``dynparam`` script needs a catkin package
    path that its packages do not install) and returns the values it then reports (the server
    clamps to the ranges and refuses invalid combinations). No changes: just the values."""
    from boids_env.eval.ros.rospy_path import import_rospy

    rospy = import_rospy()
    from dynamic_reconfigure.client import Client

    rospy.init_node("boids_reconfigure", anonymous=True, disable_signals=True)
    try:
        client = Client(node, timeout=timeout)
        config = client.update_configuration(changes) if changes else \
            client.get_configuration(timeout=timeout)
        return {k: v for k, v in dict(config).items() if k in TUNABLE}
    finally:
        rospy.signal_shutdown("done")


def values(params: ReynoldsParams) -> dict[str, float]:
    """The panel's view of ``params``."""
    current = asdict(params)
    return {name: float(current[name]) for name in TUNABLE}
