"""The cluster recipe of the docs, on this machine: a head and a second node, each with its
own temp dir and token authentication on every process; one env runner per node."""

from __future__ import annotations

import json
import os
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.mark.slow
def test_two_nodes_each_run_an_env_runner(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    ray = str(Path(sys.executable).with_name("ray"))
    # Token authentication on every process: head, second node and driver get the same
    # token (HOME apart, so that no ~/.ray/auth_token of the machine is read or written).
    environment = {
        **os.environ,
        "RAY_AUTH_MODE": "token",
        "RAY_AUTH_TOKEN": secrets.token_hex(32),
        "HOME": str(tmp_path / "home"),
        "PYTHONPATH": str(ROOT),
        "RAY_USAGE_STATS_ENABLED": "0",
    }
    (tmp_path / "home").mkdir()
    # Ray's unix sockets need a short path: the temp dirs live under a short /tmp folder.
    short = Path(tempfile.mkdtemp(prefix="rc", dir="/tmp"))
    port = free_port()
    address = f"127.0.0.1:{port}"

    def run(*command: str, timeout: int = 180) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            command,
            env=environment,
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )

    try:
        head = run(
            ray,
            "start",
            "--head",
            f"--port={port}",
            "--num-cpus=1",
            f"--temp-dir={short / 'h'}",
            "--include-dashboard=false",
        )
        assert head.returncode == 0, head.stderr[-2000:]
        node = run(
            ray, "start", f"--address={address}", "--num-cpus=1", f"--temp-dir={short / 'n'}"
        )
        assert node.returncode == 0, node.stderr[-2000:]
        run_dir = tmp_path / "run"
        trained = run(
            sys.executable,
            "-m",
            "agents.train",
            "--backend",
            "rllib",
            "--env",
            "trailer_env/Reverse-v1",
            "--algo",
            "ppo",
            "--n-trailers",
            "1",
            "--num-env-runners",
            "2",
            "--n-envs",
            "4",
            "--timesteps",
            "2000",
            "--address",
            address,
            "--run-dir",
            str(run_dir),
            timeout=400,
        )
        assert trained.returncode == 0, trained.stderr[-3000:]
        config = json.loads((run_dir / "config.json").read_text())
        runners = config["runner_envs"]
        assert len(runners) == 2 and all(native for _, native, _ in runners)
        assert len({node_id for _, _, node_id in runners}) == 2  # one runner on each node
        assert config["address"] == address
    finally:
        run(ray, "stop", "--force")
        shutil.rmtree(short, ignore_errors=True)
