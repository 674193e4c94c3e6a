"""The RLlib backend: PPO settings as on the SB3 path, checkpoints written whole,
resume, a checkpoint played outside Ray, and training on a real two-node Ray cluster.

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

import numpy as np
import pytest

from aldm_gym.agents.checkpoints import remove_temporary_files
from aldm_gym.agents.rllib import (
    STEPS_FILE,
    checkpoint_steps,
    is_checkpoint,
    newest_checkpoint,
)
from aldm_gym.agents.training import PPOParams

BIN = Path(sys.executable).parent
SHORT = {"duration": 10.0}


def _fake_checkpoint(path: Path, steps: int | None) -> Path:
    """A folder shaped like an RLlib checkpoint; complete if ``steps`` is given."""
    path.mkdir(parents=True)
    (path / "rllib_checkpoint.json").write_text("{}")
    if steps is not None:
        (path / STEPS_FILE).write_text(json.dumps({"steps": steps}))
    return path


def test_only_complete_checkpoints_are_resumed_from(tmp_path: Path) -> None:
    ckpt = tmp_path / "checkpoints"
    _fake_checkpoint(ckpt / "rllib_128", 128)
    _fake_checkpoint(ckpt / "rllib_1024", 1024)
    _fake_checkpoint(ckpt / "rllib_2048", None)  # renamed in before its steps file: never
    _fake_checkpoint(ckpt / ".rllib_4096.tmpab12", 4096)  # still being written
    newest = newest_checkpoint(tmp_path)
    assert newest == ckpt / "rllib_1024" and checkpoint_steps(newest) == 1024
    assert not is_checkpoint(ckpt / "rllib_2048")
    removed = remove_temporary_files(tmp_path)
    assert removed == [ckpt / ".rllib_4096.tmpab12"]
    assert not removed[0].exists() and (ckpt / "rllib_1024").exists()


def test_no_checkpoint_in_an_empty_folder(tmp_path: Path) -> None:
    assert newest_checkpoint(tmp_path) is None


# --- with Ray RLlib ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def rllib() -> object:
    return pytest.importorskip("ray.rllib")


def test_ppo_runs_as_on_the_sb3_path(rllib: object) -> None:
    from aldm_gym.agents.rllib import RLLIB_ENV_ID, ppo_config

    params = PPOParams(n_steps=128, learning_rate=3e-4, gamma=0.9)
    cfg = ppo_config(SHORT, params, timesteps=4096, num_env_runners=3, seed=7)
    assert cfg.env == RLLIB_ENV_ID and cfg.env_config == {"config": SHORT}
    assert cfg.train_batch_size_per_learner == 3 * 128  # n_steps per env runner
    assert cfg.minibatch_size == params.batch_size and cfg.num_epochs == params.n_epochs
    assert cfg.gamma == 0.9 and cfg.lambda_ == params.gae_lambda
    assert cfg.clip_param == params.clip_range and cfg.entropy_coeff == params.ent_coef
    assert cfg.lr == [[0, 3e-4], [4096, 0.0]]  # linear to 0 over the budget
    assert cfg.use_kl_loss is False and cfg.vf_loss_coeff == 0.5 and cfg.grad_clip == 0.5
    assert cfg.num_env_runners == 3 and cfg.seed == 7
    assert cfg.model_config["fcnet_hiddens"] == [128, 128]
    assert cfg.model_config["fcnet_activation"] == "tanh"  # as SB3's MlpPolicy
    assert cfg.model_config["vf_share_layers"] is False and cfg.vf_clip_param == float("inf")
    constant = ppo_config(SHORT, PPOParams(lr_schedule="constant"), timesteps=10)
    assert constant.lr == PPOParams.learning_rate
    assert constant.train_batch_size_per_learner == PPOParams.n_steps  # 0 runners: 1 env


@pytest.fixture(scope="module")
def trained(rllib: object, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """128 steps on one remote env runner, then resumed to 256; ``out`` given as a
    relative path (as a user types it)."""
    from aldm_gym.agents.rllib import train_rllib

    out = tmp_path_factory.mktemp("rllib")
    kwargs = {
        "num_env_runners": 1,
        "duration": 10.0,
        "params": PPOParams(n_steps=64),
        "checkpoint_freq": 128,
        "progress": False,
    }
    cwd = os.getcwd()
    os.chdir(out.parent)
    try:
        relative = Path(out.name)
        assert train_rllib(relative, timesteps=128, **kwargs) == 128
        assert train_rllib(relative, timesteps=256, resume=True, **kwargs) == 256
    finally:
        os.chdir(cwd)
    return out


def test_training_writes_checkpoints_and_resumes(trained: Path) -> None:
    from aldm_gym.agents.rllib import MODEL_DIR, train_rllib

    meta = json.loads((trained / "training.json").read_text())
    assert meta["backend"] == "rllib" and meta["timesteps"] == 256
    assert meta["env_config"]["duration"] == 10.0 and meta["ppo"]["n_steps"] == 64
    names = sorted(p.name for p in (trained / "checkpoints").iterdir())
    assert names == ["rllib_128", "rllib_256"]
    assert checkpoint_steps(trained / MODEL_DIR) == 256
    events = list((trained / "tb" / "RLlib_PPO").glob("events.out.tfevents.*"))
    assert len(events) == 2  # one per run, in the same tensorboard run
    with pytest.raises(FileExistsError, match="already holds a training"):
        train_rllib(trained, timesteps=512, progress=False)


def _observations_seen(checkpoint: Path) -> int:
    """How many observations the checkpoint's normalisation statistics count."""
    from aldm_gym.agents.rllib import RLlibPolicy

    state = RLlibPolicy(checkpoint).pipeline.get_state()
    return int(state["MeanStdFilter"][None]["running_stats"][0]["num_pushes"])


def test_checkpoints_carry_the_runners_statistics_across_a_resume(trained: Path) -> None:
    # 128 steps (and the resets' observations) before the resume ...
    first = _observations_seen(trained / "checkpoints" / "rllib_128")
    assert 128 <= first < 200
    # ... and the resumed runner started from them: 128 more, not from zero.
    assert _observations_seen(trained / "rllib_model") >= first + 128


def test_resume_falls_back_to_an_older_checkpoint(trained: Path, tmp_path: Path) -> None:
    import shutil

    from aldm_gym.agents.checkpoints import TrainingWarning
    from aldm_gym.agents.rllib import train_rllib

    out = tmp_path / "out"
    shutil.copytree(trained, out, ignore=shutil.ignore_patterns("train.lock"))
    for path in (out / "checkpoints" / "rllib_256").rglob("*.pkl"):
        path.write_bytes(b"damaged")
    with pytest.warns(TrainingWarning, match="skipping .*rllib_256: does not restore"):
        steps = train_rllib(out, timesteps=320, resume=True, progress=False)
    assert steps == 320  # from 128, not from 0 nor from the damaged 256
    assert checkpoint_steps(out / "checkpoints" / "rllib_256") == 256  # written anew
    assert _observations_seen(out / "checkpoints" / "rllib_256") >= 256


def test_a_closed_port_is_one_line_and_exit_2(
    rllib: object, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from _cli import usage_error

    argv = ["train", "--backend", "rllib", "--address", f"127.0.0.1:{_free_port()}"]
    line = usage_error([*argv, "--out", str(tmp_path / "t")], capsys)
    assert "argument --address: no Ray cluster answers at 127.0.0.1:" in line
    assert not (tmp_path / "t" / "training.json").exists()  # nothing to clean up


def test_an_iteration_that_sampled_nothing_counts_no_steps() -> None:
    from aldm_gym.agents.rllib import _sampled

    assert _sampled({"env_runners": {"num_env_steps_sampled": 256}}) == 256
    for result in ({"env_runners": {"num_env_steps_sampled": float("nan")}}, {}):
        with pytest.warns(UserWarning, match="sampled no env steps"):
            assert _sampled(result) == 0


def test_an_sb3_training_is_not_resumed_by_rllib(rllib: object, tmp_path: Path) -> None:
    from aldm_gym.agents.rllib import train_rllib

    (tmp_path / "training.json").write_text(json.dumps({"env_config": {}, "ppo": {}}))
    with pytest.raises(ValueError, match="holds an SB3 training"):
        train_rllib(tmp_path, resume=True, progress=False)


def test_a_checkpoint_plays_outside_ray_with_frozen_statistics(trained: Path) -> None:
    import gymnasium as gym

    from aldm_gym import ENV_ID
    from aldm_gym.agents.checkpoints import load_policy

    policy, meta = load_policy(trained / "rllib_model")
    assert policy.num_timesteps == 256 and meta["backend"] == "rllib"
    state = json.dumps(policy.pipeline.get_state(), default=str)
    env = gym.make(ENV_ID, config=meta["env_config"])
    obs, _ = env.reset(seed=3)
    for _ in range(5):
        logits = policy.logits(obs)
        assert logits.shape == (env.action_space.n,) and np.isfinite(logits).all()
        action, _ = policy.predict(obs, deterministic=True)
        assert int(action) == int(np.argmax(logits))
        assert policy.predict(obs)[0] == action  # the same observation, the same action
        obs, *_ = env.step(action)
    env.close()
    # Stochastic play samples the softmax of the logits.
    drawn = [int(policy.predict(obs, deterministic=False)[0]) for _ in range(300)]
    p = np.exp(policy.logits(obs) - policy.logits(obs).max())
    p /= p.sum()
    counts = np.bincount(drawn, minlength=len(p))
    assert np.all(np.abs(counts / 300 - p) < 0.1)
    assert json.dumps(policy.pipeline.get_state(), default=str) == state


def test_evaluate_plays_an_rllib_checkpoint_against_the_baselines(trained: Path) -> None:
    from aldm_gym.agents.model_evaluation import evaluate

    rows, info = evaluate(trained / "checkpoints" / "rllib_128", episodes=2, progress=False)
    assert [r["policy"] for r in rows] == ["idle", "rule_based", "model"]
    assert info["timesteps"] == 128 and len(info["per_episode"]["model"]["mean_speed"]) == 2


def test_a_damaged_checkpoint_names_the_folder(trained: Path, tmp_path: Path) -> None:
    import shutil

    from aldm_gym.agents.rllib import load_rllib_policy

    out = tmp_path / "out"
    shutil.copytree(trained, out, ignore=shutil.ignore_patterns("train.lock"))
    module = out / "rllib_model" / "learner_group" / "learner" / "rl_module" / "default_policy"
    for path in module.rglob("*.pkl"):
        path.write_bytes(b"not a pickle")
    with pytest.raises(ValueError, match="rllib_model: not a readable RLlib checkpoint"):
        load_rllib_policy(out / "rllib_model")


# --- a real two-node cluster --------------------------------------------------------------


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
    argv = [str(BIN / "aldm-gym"), "train", "--backend", "rllib", "--address", address]
    too_many = subprocess.run(
        [*argv, "--num-env-runners", "3", "--out", str(tmp_path / "too_many")],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert too_many.returncode == 2 and "Traceback" not in too_many.stderr
    assert "argument --num-env-runners: the Ray cluster at" in too_many.stderr
    assert "has 2 CPUs; 3 env runners need one each" in too_many.stderr
    # Two env runners needing one CPU each on two one-CPU nodes: one runs on each node.
    train = subprocess.run(
        [
            str(BIN / "aldm-gym"),
            "train",
            "--backend",
            "rllib",
            "--address",
            address,
            "--num-env-runners",
            "2",
            "--timesteps",
            "384",
            "--n-steps",
            "64",
            "--duration",
            "10",
            "--out",
            str(out),
            "--no-progress",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert train.returncode == 0, train.stderr[-3000:]
    assert f"wrote {out / 'rllib_model'}" in train.stdout
    meta = json.loads((out / "training.json").read_text())
    assert meta["num_env_runners"] == 2 and meta["backend"] == "rllib"
    assert checkpoint_steps(out / "rllib_model") >= 384
    evaluate = subprocess.run(
        [
            str(BIN / "aldm-gym"),
            "evaluate",
            "--model",
            str(out / "rllib_model"),
            "--episodes",
            "2",
            "--no-progress",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert evaluate.returncode == 0, evaluate.stderr[-3000:]
    record = json.loads((out / "evaluate_rllib_model_aldm_per_dash.json").read_text())
    assert [r["policy"] for r in record["rows"]] == ["idle", "rule_based", "model"]
    assert record["timesteps"] >= 384


@pytest.mark.slow
def test_sigterm_finishes_the_iteration_and_saves_it(rllib: object, tmp_path: Path) -> None:
    import signal

    out = tmp_path / "out"
    argv = [str(BIN / "aldm-gym"), "train", "--backend", "rllib", "--num-env-runners", "1"]
    argv += ["--timesteps", "100000", "--n-steps", "64", "--duration", "10"]
    argv += ["--checkpoint-freq", "100000", "--out", str(out), "--no-progress"]
    proc = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 300
        while not list((out / "tb").rglob("events.out.tfevents.*")):  # training has begun
            assert proc.poll() is None and time.monotonic() < end, proc.stderr.read()[-2000:]
            time.sleep(0.2)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err[-2000:]
    assert "stopping after this iteration" in err and "continue with --resume" in err
    saved = newest_checkpoint(out)
    assert saved is not None and checkpoint_steps(saved) >= 64  # no checkpoint was due
