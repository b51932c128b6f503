"""The controller node ends by itself once its ticks stop (the simulator ended): the
roboticist's tutorial leaves no command running. No ROS needed: the graph's controller core
over a transport of the test's own."""

import threading
import time

import pytest

from boids_env import BoidsEnv
from boids_env.eval.graph.controller import ControllerCore, ControllerOptions, controller_policy


class _Silent:
    """A graph on which the simulator sent ``ticks`` ticks and then left."""

    def __init__(self):
        self.core = None
        self.stop = threading.Event()

    def stopped(self):
        return self.stop.is_set()

    def answer(self, tick):
        return self.core.answer(tick)


def _controller(idle_exit, ticks=3, quiet=True):
    options = ControllerOptions(quiet=quiet, idle_exit=idle_exit)
    config = BoidsEnv(robots=4).config
    core = ControllerCore(options, controller_policy(options), config, "/c", lambda _s: None)
    for k in range(ticks):  # every robot's odometry of tick k, as the sim publishes it
        stamp = round(k * config.world.dt * 1e9)
        for source in range(4):
            core.odometry(source, stamp, float(source), 0.0, 0.0, 0.0)
    transport = _Silent()
    transport.core = core
    return core, transport


def test_the_controller_exits_once_the_ticks_stop(capsys):
    core, transport = _controller(idle_exit=0.5, quiet=False)
    began = time.monotonic()
    assert core.spin(transport) == 3
    assert time.monotonic() - began < 10
    assert "no tick for 0.5 s" in capsys.readouterr().out


def test_idle_exit_zero_runs_until_stopped():
    core, transport = _controller(idle_exit=0)
    timer = threading.Timer(1.5, transport.stop.set)
    timer.start()
    began = time.monotonic()
    assert core.spin(transport) == 3
    assert time.monotonic() - began >= 1.4  # it waited for the stop, not for an idle limit
    timer.cancel()


@pytest.mark.parametrize("value", [-1, float("nan"), True, 1e9])
def test_a_bad_idle_exit_is_refused_by_name(value):
    with pytest.raises(ValueError, match="idle_exit"):
        ControllerOptions(idle_exit=value)
