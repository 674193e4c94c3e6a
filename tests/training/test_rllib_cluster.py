"""The RLlib backend on a real two-node Ray cluster started on this machine, and a
cluster that is not there.

Tests needing Ray RLlib skip without the ``[ray]`` extra (``make test-ray`` runs them).
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from aldm_gym.training.rllib.checkpoints import checkpoint_steps

BIN = Path(sys.executable).parent


def test_a_closed_port_is_one_line_and_exit_2(
    rllib: object, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from _cli import usage_error

    argv = ["train", "--backend", "rllib", "--address", f"127.0.0.1:{_free_port()}"]
    line = usage_error([*argv, "--out", str(tmp_path / "t")], capsys)
    assert "argument --address: no Ray cluster answers at 127.0.0.1:" in line
    assert not (tmp_path / "t" / "training.json").exists()  # nothing to clean up


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_for(port: int, timeout: float = 60.0) -> None:
    """Return once the head accepts connections on ``port`` (fail after ``timeout``)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=1.0):
                return
        except OSError:
            time.sleep(0.2)
    pytest.fail(f"the Ray head did not open port {port}")


def _nodes_alive(address: str, env: dict[str, str]) -> int:
    status = subprocess.run(
        [str(BIN / "ray"), "status", "--address", address],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    if "Active:" not in status.stdout:  # the head is not answering yet
        return 0
    active = status.stdout.split("Active:")[1].split("Pending:")[0]
    return active.count("node_")


@pytest.fixture()
def ray_cluster(rllib: object, tmp_path: Path) -> Iterator[tuple[str, dict[str, str]]]:
    """A head and a second node on 127.0.0.1 (one CPU each, a token of their own),
    each a ``ray start --block`` process, ended (and its Ray processes with it) after."""
    port = _free_port()
    token = tmp_path / "ray_token"
    token.write_text(os.urandom(32).hex())
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(token)}
    common = ["--block", "--node-ip-address", "127.0.0.1", "--num-cpus", "1"]
    common += ["--disable-usage-stats"]
    ray = str(BIN / "ray")
    log = open(tmp_path / "ray.log", "w")  # closed in the finally below
    nodes = [
        subprocess.Popen(
            [ray, "start", "--head", "--port", str(port), "--include-dashboard", "false", *common],
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    ]
    address = f"127.0.0.1:{port}"
    try:
        _wait_for(port)
        nodes.append(
            subprocess.Popen(
                [ray, "start", "--address", address, *common],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        )
        end = time.monotonic() + 60
        while _nodes_alive(address, env) < 2:
            assert time.monotonic() < end, (tmp_path / "ray.log").read_text()[-2000:]
            time.sleep(0.5)
        yield address, env
    finally:
        for node in reversed(nodes):
            node.terminate()
            try:
                node.wait(timeout=60)
            except subprocess.TimeoutExpired:
                node.kill()
        log.close()


@pytest.mark.slow
def test_train_on_a_two_node_cluster_and_evaluate(
    ray_cluster: tuple[str, dict[str, str]], tmp_path: Path
) -> None:
    address, env = ray_cluster
    out = tmp_path / "train"

    def aldm_gym(*args: str, timeout: float) -> subprocess.CompletedProcess:
        return subprocess.run(
            [str(BIN / "aldm-gym"), *args],
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )

    argv = ["train", "--backend", "rllib", "--address", address]
    too_many = aldm_gym(
        *argv, "--num-env-runners", "3", "--out", str(tmp_path / "too_many"), timeout=300
    )
    assert too_many.returncode == 2 and "Traceback" not in too_many.stderr
    assert "argument --num-env-runners: the Ray cluster at" in too_many.stderr
    assert "has 2 CPUs; 3 env runners need one each" in too_many.stderr
    # Two env runners needing one CPU each on two one-CPU nodes: one runs on each node.
    run = ("--num-env-runners", "2", "--timesteps", "384", "--n-steps", "64", "--duration", "10")
    train = aldm_gym(*argv, *run, "--out", str(out), "--no-progress", timeout=600)
    assert train.returncode == 0, train.stderr[-3000:]
    assert f"wrote {out / 'rllib_model'}" in train.stdout
    meta = json.loads((out / "training.json").read_text())
    assert meta["num_env_runners"] == 2 and meta["backend"] == "rllib"
    assert checkpoint_steps(out / "rllib_model") >= 384
    model = str(out / "rllib_model")
    evaluate = aldm_gym(
        "evaluate", "--model", model, "--episodes", "2", "--no-progress", timeout=600
    )
    assert evaluate.returncode == 0, evaluate.stderr[-3000:]
    record = json.loads((out / "evaluate_rllib_model_aldm_per_dash.json").read_text())
    assert [r["policy"] for r in record["rows"]] == ["idle", "rule_based", "model"]
    assert record["timesteps"] >= 384
