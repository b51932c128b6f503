"""``boids run --live foxglove``: a headless WebSocket client speaking Foxglove's protocol
(``foxglove.sdk.v1``) sees the server advertise its channels, subscribes, and receives
every robot pose of a whole episode, decoded with the protobuf schema the server advertised.

Without the ``live`` extra (foxglove-sdk) these tests are skipped, unless
``BOIDS_REQUIRE_LIVE=1`` (CI sets it) makes that a failure."""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import threading
import time

import numpy as np
import pytest


def _require(module: str):
    try:
        return pytest.importorskip(module)
    except pytest.skip.Exception:
        if os.environ.get("BOIDS_REQUIRE_LIVE") == "1":
            pytest.fail(f"BOIDS_REQUIRE_LIVE=1 but {module} is missing")
        raise


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _message_class(channel: dict):
    """The protobuf class of an advertised channel, from its FileDescriptorSet."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for f in files.file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))


def _client(port: int, received: dict, done: threading.Event, errors: list) -> None:
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    try:
        for _ in range(200):  # the server starts with the run
            try:
                ws = connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"],
                             open_timeout=2)
                break
            except OSError:
                time.sleep(0.05)
        else:
            raise AssertionError("no live view server")
        with ws:
            channels: dict[int, dict] = {}
            subscribed = False
            while not done.is_set():
                try:
                    frame = ws.recv(timeout=20)
                except (TimeoutError, ConnectionClosed):  # the run ended, its server stopped
                    break
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    received.setdefault("ops", []).append(msg["op"])
                    if msg["op"] == "advertise":
                        channels.update({c["id"]: c for c in msg["channels"]})
                        received["channels"] = dict(channels)
                    wanted = {c["topic"]: c["id"] for c in channels.values()}
                    if not subscribed and {"/robots", "/metrics", "/scene", "/tf"} <= set(wanted):
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                            {"id": i, "channelId": wanted[t]}
                            for i, t in enumerate(("/robots", "/metrics", "/scene", "/tf"))]}))
                        subscribed = True
                    continue
                assert frame[0] == 0x01, frame[:1]  # message data
                sub, log_time = struct.unpack_from("<IQ", frame, 1)
                received.setdefault(sub, []).append((log_time, bytes(frame[13:])))
    except Exception as exc:  # reported by the test
        errors.append(exc)


def test_a_websocket_client_receives_every_pose_of_an_episode():
    _require("foxglove")
    _require("websockets")
    _require("google.protobuf")
    from boids_env.eval.run import run

    port = _free_port()
    received: dict = {}
    done = threading.Event()
    errors: list = []
    client = threading.Thread(target=_client, args=(port, received, done, errors),
                              daemon=True)
    client.start()
    result = run("reynolds", out=None, seed=0, quiet=True, env_fields={"max_cycles": 150},
                 live={"port": port, "speed": 25.0, "wait": 30.0})
    time.sleep(0.5)
    done.set()
    client.join(30)
    assert not errors, errors
    assert received.get("ops", [])[:2] == ["serverInfo", "advertise"], received.get("ops")
    topics = {c["topic"]: c for c in received["channels"].values()}
    assert topics["/robots"]["schemaName"] == "foxglove.PosesInFrame"
    assert topics["/scene"]["schemaName"] == "foxglove.SceneUpdate"
    assert topics["/robots"]["encoding"] == "protobuf"
    poses = received.get(0, [])
    positions = result.recording.positions  # (151, 13, 2)
    assert len(poses) == len(positions), (len(poses), len(positions))
    Poses = _message_class(topics["/robots"])
    times = [t for t, _ in poses]
    assert times == sorted(times) and len(set(times)) == len(times)
    assert times[1] - times[0] == 100_000_000  # dt
    for step, (_, payload) in enumerate(poses):
        msg = Poses.FromString(payload)
        got = np.array([[p.position.x, p.position.y] for p in msg.poses])
        assert msg.frame_id == "map"
        np.testing.assert_array_equal(got, positions[step], err_msg=f"step {step}")
    metrics = [json.loads(p) for _, p in received[1]]
    assert metrics[-1]["V_sep"] == pytest.approx(result.metrics["V_sep"])
    scene = _message_class(topics["/scene"]).FromString(received[2][0][1])
    ids = {e.id for e in scene.entities}
    assert {"robots", "walls"} <= ids, ids
    assert len(next(e for e in scene.entities if e.id == "robots").spheres) == 13


def test_live_flags_without_live_and_bad_values_are_refused_before_anything_runs(capsys):
    from boids_env.config import EnvConfig
    from boids_env.train.cli import main

    assert main(["run", "--live-port", "9000"]) != 0
    assert "add --live foxglove" in capsys.readouterr().err
    _require("foxglove")
    from boids_env.eval.liveview import FoxgloveView

    with pytest.raises(ValueError, match="speed must be in"):
        FoxgloveView(EnvConfig(), port=0, speed=-1.0)
    with pytest.raises(ValueError, match="port must be"):
        FoxgloveView(EnvConfig(), port=70000)


@pytest.mark.parametrize("command", [["run"], ["ros2", "sim", "--no-wait", "--listen",
                                               "tcp/127.0.0.1:0", "--connect",
                                               "tcp/127.0.0.1:9"]])
def test_a_taken_live_port_is_refused_by_name_before_anything_runs(command, tmp_path):
    """Issue 55: a port already in use ends the command with exit status 2 and one line
    naming the port and how to choose another, before any output or network; no
    traceback."""
    import subprocess
    import sys

    _require("foxglove")
    if command[0] == "ros2":
        _require("zenoh")
    out = tmp_path / "out"
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = subprocess.run(
            [sys.executable, "-m", "boids_env.train.cli", *command, "--max-cycles", "5",
             "--live", "foxglove", "--live-port", str(port), "--out", str(out)],
            capture_output=True, text=True, timeout=120,
            env={**os.environ, "SDL_VIDEODRIVER": "dummy"})
    assert done.returncode == 2, done.stderr[-3000:]
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    assert f"port {port}" in done.stderr and "--live-port" in done.stderr, done.stderr
    assert "--live-port 0" in done.stderr  # any free port
    assert not out.exists()  # refused before any side effect
    assert done.stdout == ""


def test_the_view_itself_refuses_a_taken_port_with_a_value_error():
    """The same refusal from :class:`FoxgloveView` (the library's users, and a port taken
    between the command's check and the server's start)."""
    _require("foxglove")
    from boids_env.config import EnvConfig
    from boids_env.eval.liveview import FoxgloveView

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(ValueError, match=f"port {port} .*--live-port"):
            FoxgloveView(EnvConfig(), port=port)
