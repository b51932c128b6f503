"""The live window's key handling (headless: plain logic, and the loop with scripted keys)."""

import os
import subprocess
import sys

import numpy as np
import pytest

from boids_env.eval.live import LiveControls, run_live
from boids_env.policies.reynolds_params import reynolds_params


def test_arrows_drive_the_leader_at_its_speed():
    c = LiveControls(None, leader_speed=0.5)
    assert np.array_equal(c.leader_command(), [0, 0])
    c.key_down("up")
    assert np.allclose(c.leader_command(), [0, 0.5])
    c.key_down("right")
    assert np.allclose(c.leader_command(), [0.5 / np.sqrt(2)] * 2)
    c.key_up("up")
    c.key_up("right")
    assert np.array_equal(c.leader_command(), [0, 0])


def test_keys_tune_the_selected_parameter_and_show_it():
    c = LiveControls(reynolds_params("paper"))
    c.key_down("4")
    c.key_down("+")
    c.key_down("=")
    assert c.params.leader_weight == pytest.approx(1.2)
    c.key_down("5")
    c.key_down("-")
    assert c.params.horizon == pytest.approx(0.95)
    assert any(line.startswith(">5 horizon 0.95") for line in c.hud_lines())


def test_invalid_values_are_refused_with_a_message():
    c = LiveControls(reynolds_params("paper", separation_weight=0.05))
    before = c.params
    c.key_down("1")
    c.key_down("-")
    assert c.params == before and "separation_weight must be" in c.message
    c.key_down("5")
    for _ in range(30):
        c.key_down("+")
    assert c.params.horizon == pytest.approx(2.0) and "horizon must be <=" in c.message
    assert LiveControls(None).hud_lines()[-1].startswith("arrows")


def test_flags():
    c = LiveControls(None)
    for key in ("space", "f", "r", "q"):
        c.key_down(key)
    assert c.paused and c.fast and c.restart and c.quit
    c.key_down("space")
    assert not c.paused


def test_live_loop_with_scripted_keys(monkeypatch):
    import pygame

    script = ([[("down", "4"), ("down", "+")], [("down", "right")]] + [[]] * 30
              + [[("down", "q")]])
    calls = iter(script)

    def fake_get():
        keys = next(calls, [("down", "q")])
        return [pygame.event.Event(pygame.KEYDOWN if kind == "down" else pygame.KEYUP,
                                   key=pygame.key.key_code(name)) for kind, name in keys]

    monkeypatch.setattr(pygame.event, "get", fake_get)
    controls, metrics = run_live("reynolds", env_fields={"path": "external", "robots": 5})
    assert controls.params.leader_weight == pytest.approx(1.1)
    assert metrics["steps"] == 32  # one step per frame until q
    # the keyboard-driven leader goes right at 0.55 m/s once the 2 s start-up is over:
    # about 11 steps of 0.055 m
    x, y = metrics["leader_position"]
    assert 0.4 < x < 0.8 and abs(y) < 0.05


def test_messages_fade_after_a_few_seconds():
    now = [100.0]
    c = LiveControls(reynolds_params("paper"), clock=lambda: now[0])
    assert c.message_opacity() == 0.0, "no message yet"
    c.key_down("+")
    assert c.message == "separation_weight = 1.1"
    assert c.message_opacity() == 1.0
    now[0] += 2.9
    assert c.message_opacity() == 1.0, "fully shown for 3 s"
    now[0] += 0.6
    assert c.message_opacity() == pytest.approx(0.5), "then fading"
    now[0] += 1.0
    assert c.message_opacity() == 0.0, "gone after 4 s"
    c.key_down("-")
    assert c.message_opacity() == 1.0, "a new message shows again"
    assert all(c.message not in line for line in c.hud_lines()), \
        "the message is drawn apart (fading), not among the help lines"


def test_the_live_window_prints_the_run_metrics_table_on_exit(monkeypatch, capsys):
    from boids_env.eval import live
    from boids_env.train.cli import main

    metrics = {"V_sep": 0.5, "V_coh": 0.0, "V_align": 1.25, "duration": 3.0,
               "touching_fraction": 0.1, "contacts_follower": 2.0}
    monkeypatch.setattr(live, "run_live", lambda *a, **k: (None, metrics))
    assert main(["run", "--render", "human"]) == 0
    out = capsys.readouterr().out
    assert "{" not in out, f"no raw dict: {out}"
    assert "V_align" in out and "1.2500" in out and "alignment violation (study)" in out, out
    assert "contacts_follower" in out and " 2  " in out, out


def test_no_display_is_a_clear_cli_error(monkeypatch, capsys):
    from boids_env.eval import live
    from boids_env.render import NoDisplayError
    from boids_env.train.cli import main

    def no_display(*args, **kwargs):
        raise NoDisplayError("no display for the live window (DISPLAY is not set)")

    monkeypatch.setattr(live, "run_live", no_display)
    assert main(["run", "--render", "human"]) == 2
    assert "no display" in capsys.readouterr().err


def test_the_live_window_is_refused_headless_though_the_env_only_warns():
    """The env's human mode draws off-screen without a display (Gymnasium's check_env opens
    it); the live window, which someone means to watch, still stops with the clear error."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("SDL_VIDEODRIVER", "DISPLAY", "WAYLAND_DISPLAY")}
    out = subprocess.run([sys.executable, "-m", "boids_env.train.cli", "run", "--render",
                          "human"], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "no display for the live window" in out.stderr, out.stderr


def test_the_live_loop_reports_the_safety_metrics(monkeypatch):
    import pygame

    keys = iter([[("down", "q")] if i == 25 else [] for i in range(26)])
    monkeypatch.setattr(pygame.event, "get", lambda: [
        pygame.event.Event(pygame.KEYDOWN, key=pygame.key.key_code(name))
        for _, name in next(keys, [("down", "q")])])
    _, metrics = run_live("reynolds", env_fields={"robots": 5})
    assert metrics["steps"] == 25
    assert {"touching_fraction", "mean_nn_distance", "polarization"} <= metrics.keys()
