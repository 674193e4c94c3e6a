"""PPO on stable-baselines3: :class:`SB3Backend` and :func:`train` (``aldm-gym train``).

:func:`train` fits a stable-baselines3 PPO ``MultiInputPolicy`` on the meta actions
(``Discrete(5)``) of ``ALDMHighway-v0`` with the observation built from one detector's
lanes (``naive``, ``aldm`` or ``ground_truth``). Environments run vectorised
(``SubprocVecEnv`` for more than one), observations are normalised with running
statistics (``VecNormalize``), tensorboard logs go to ``<out>/tb/`` and
checkpoints to ``<out>/checkpoints/`` every ``checkpoint_freq`` steps (between
rollouts) and on an interruption (Ctrl-C, SIGTERM). ``resume=True`` continues from the
newest intact checkpoint with the settings, step count, tensorboard run, optimiser
state, normalisation statistics, envs and RNG states of the interrupted run: with the
same ``n_envs`` and ``seed`` it trains on exactly as the uninterrupted run would have.
The output folder's files are listed in :mod:`aldm_gym.training.outputs`; what every
training does (lock, signals, fallback to an intact checkpoint, ``training.json``) is
:func:`~aldm_gym.training.backend.train_with`'s; the callbacks that checkpoint,
validate and show progress are in :mod:`aldm_gym.training.sb3.callbacks`.

Validation: every ``validation_freq`` steps (after the PPO update that ends a rollout),
at the end, and at step 0 for a model cloned from the rule-based LCA
(``pretrain_episodes``, :mod:`aldm_gym.training.sb3.pretrain`), the current policy
drives ``validation_episodes`` episodes with the fixed seeds ``VALIDATION_SEED ..``
(deterministic actions), disjoint from the training envs' seeds (``seed ..``) and from
:func:`~aldm_gym.training.model_evaluation.evaluate`'s (``10000 ..``). The policy with
the highest mean episode return (the env's reward, i.e. the objective the training
optimises) is kept as ``best_model.zip``. PPO on this task is not monotone: collisions
are rare events and successive checkpoints of one run differ by several collisions in
30 episodes, so choosing on held-out seeds is what makes a training's result
reproducible without peeking at the evaluation seeds.

Why PPO rather than DQN: PPO is on-policy and collects its rollouts from all vectorised
environments at once, which is how the two cores of this machine are used (the env, not
the network, is the bottleneck); it is robust to hyperparameters on highway-env's meta
actions (highway-env's own PPO example trains in ~2e4 steps), and its state is the
weights, the optimiser, the step count and the envs', so a resume loses nothing. DQN
would also need its replay buffer checkpointed (hundreds of MB of Dict observations)
for an exact resume.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any, ClassVar

from aldm_gym.errors import ConfigError
from aldm_gym.training.backend import Backend, CheckpointRef, train_with
from aldm_gym.training.outputs import (
    MODEL_FILE,
    TENSORBOARD_DIR,
    VECNORM_FILE,
    write_bytes_atomic,
)
from aldm_gym.training.progress import report
from aldm_gym.training.record import BACKEND_RUN_SETTINGS, TrainingRecord
from aldm_gym.training.sb3 import import_sb3, model_class
from aldm_gym.training.sb3.checkpoints import (
    Checkpoint,
    Snapshot,
    checkpoint_fault,
    checkpoints,
    restore_resume_state,
    take_snapshot,
)
from aldm_gym.training.sb3.envs import close_envs, make_vec_env
from aldm_gym.training.sb3.pretrain import (
    check_pretrain,
    clone,
    collect_demonstrations,
    demonstration_seeds,
)
from aldm_gym.training.settings import (
    DEFAULT_COLLISION_REWARD,
    DEFAULT_PRETRAIN_EPOCHS,
    PPOParams,
    algorithm_name,
    check_keep_by,
    env_config,
)
from aldm_gym.training.signals import StopRequest

RUN_SETTINGS = BACKEND_RUN_SETTINGS["sb3"]
"""Settings of a run that ``resume`` restores from ``training.json`` unless given."""


class SB3Backend(Backend[Checkpoint]):
    """PPO on stable-baselines3 (see the module docstring).

    Its chunks are SB3's rollouts; the callbacks snapshot the training at the start of
    each, so the last consistent state is always at hand and the first signal stops
    it at once (:attr:`stops_at_once`).

    :param verbose: SB3's verbosity.
    :param callback: extra SB3 callback(s) (a list or one).
    :param pretrain_episodes: a new model is first cloned from the rule-based LCA
        played on this many episodes (0: not; :mod:`aldm_gym.training.sb3.pretrain`).
        A resume takes both cloning settings from ``training.json``'s ``"pretrain"``.
    :param pretrain_epochs: passes of the cloning over the demonstrations.
    :param keep_by: what the validation keeps the best model by (``"return"`` or
        ``"score"``; None: the saved one on a resume, else ``"return"``).
    :ivar model: the SB3 PPO model (None before :meth:`build` or :meth:`restore`).
    """

    name: ClassVar[str] = "sb3"
    stops_at_once: ClassVar[bool] = True
    algorithms: ClassVar[tuple[str, ...]] = ("PPO", "MaskablePPO")

    def __init__(
        self,
        out: Path,
        record: TrainingRecord,
        saved: TrainingRecord | None,
        progress: bool,
        verbose: int = 0,
        callback: Any = None,
        pretrain_episodes: int = 0,
        pretrain_epochs: int = DEFAULT_PRETRAIN_EPOCHS,
        keep_by: str | None = None,
    ) -> None:
        super().__init__(out, record, saved, progress)
        was = None if saved is None else saved.keep_by  # a resume keeps the training's own
        if keep_by is not None:
            check_keep_by(keep_by)
            if was is not None and keep_by != was:
                raise ConfigError(
                    f"keep_by={keep_by!r}, but the training being resumed keeps its best "
                    f"model by {was!r} (its best_model.zip was chosen so)"
                )
        self.record = replace(self.record, keep_by=keep_by or was or "return")
        self.verbose = verbose
        self.callback = callback
        self.pretrain_episodes = pretrain_episodes
        self.pretrain_epochs = pretrain_epochs
        if saved is not None:  # a resume keeps the training's own (none: no cloning)
            cloned = saved.pretrain or {"episodes": 0, "epochs": pretrain_epochs}
            self.pretrain_episodes = int(cloned["episodes"])
            self.pretrain_epochs = int(cloned["epochs"])
        self.clone_pending = False
        self.model: Any = None
        self.venv: Any = None
        self.done = 0
        self.resumed = False
        self.checkpointer: Any = None
        self.final: Snapshot | None = None

    @staticmethod
    def require() -> None:
        """Import stable-baselines3 and torch (:func:`~aldm_gym.training.sb3.import_sb3`)."""
        import_sb3()

    @classmethod
    def require_algorithm(cls, algorithm: str) -> None:
        """Refuse an unknown algorithm; import sb3-contrib for MaskablePPO."""
        super().require_algorithm(algorithm)
        model_class(algorithm)

    @contextmanager
    def session(self) -> Iterator[None]:
        """Torch on one thread: the envs need the cores; the MLP is tiny."""
        import torch

        torch.set_num_threads(1)
        yield

    def checkpoints(self) -> list[Checkpoint]:
        """The SB3 checkpoints of the output folder, newest first."""
        return checkpoints(self.out)

    def checkpoint_fault(self, checkpoint: Checkpoint) -> str | None:
        """Why a checkpoint's files cannot be used (sha256 against its manifest)."""
        return checkpoint_fault(self.out, checkpoint.steps)

    def restore(self, checkpoint: Checkpoint) -> str:
        """Load the model and normalisation of ``checkpoint`` onto new envs; with the
        saved ``n_envs`` and ``seed``, put the envs and RNGs back as they were."""
        from stable_baselines3.common.vec_env import VecNormalize

        run, saved = self.record.run, self.saved
        done = checkpoint.steps
        exact = (
            checkpoint.resume_state is not None
            and saved is not None
            and run.n_envs == saved.run.n_envs
            and run.seed == saved.run.seed
        )
        self.venv = make_vec_env(self.record.env_config, run.n_envs, run.seed + done)
        self.venv = VecNormalize.load(str(checkpoint.vecnormalize), self.venv)
        self.venv.training = True
        # load takes n_envs from venv and rebuilds the rollout buffer for it.
        self.model = model_class(self.record.algorithm).load(
            checkpoint.model, env=self.venv, device="cpu"
        )
        self.model.tensorboard_log = str(self.out / TENSORBOARD_DIR)
        self.done, self.resumed = done, True
        if saved is not None and saved.pretrain:
            self.record = replace(self.record, pretrain=saved.pretrain)
        if exact:
            assert checkpoint.resume_state is not None
            restore_resume_state(self.model, checkpoint.resume_state)
            return f"envs and RNGs continue exactly from {checkpoint.model.name}"
        self.model.set_random_seed(run.seed + done)
        return (
            f"envs restart from seed {run.seed + done} (n_envs or seed changed, "
            "or the checkpoint has no resume state)"
        )

    def build(self) -> None:
        """A new model (PPO or MaskablePPO) on new, normalised envs."""
        from stable_baselines3.common.vec_env import VecNormalize

        run, params = self.record.run, self.params
        self.venv = VecNormalize(
            make_vec_env(self.record.env_config, run.n_envs, run.seed),
            norm_reward=False,
            clip_obs=10.0,
        )
        self.model = model_class(self.record.algorithm)(
            "MultiInputPolicy",
            self.venv,
            n_steps=params.n_steps,
            batch_size=min(params.batch_size, params.n_steps * run.n_envs),
            n_epochs=params.n_epochs,
            learning_rate=params.learning_rate_schedule(),
            gamma=params.gamma,
            gae_lambda=params.gae_lambda,
            ent_coef=params.ent_coef,
            clip_range=params.clip_range,
            policy_kwargs={"net_arch": list(params.net_arch)},
            tensorboard_log=str(self.out / TENSORBOARD_DIR),
            seed=run.seed,
            device="cpu",
            verbose=self.verbose,
        )
        if self.pretrain_episodes > 0:
            # The cloning itself runs in learn (a signal stops it there); the settings
            # go to training.json first, so a resume of a stopped cloning clones again.
            self.record = replace(
                self.record,
                pretrain={"episodes": self.pretrain_episodes, "epochs": self.pretrain_epochs},
            )
            self.clone_pending = True

    def _pretrain(self) -> None:
        """Clone the rule-based LCA into the new model
        (:mod:`aldm_gym.training.sb3.pretrain`); the report replaces the settings in
        ``training.json``'s ``"pretrain"``."""
        record = self.record
        seeds = demonstration_seeds(record.run.seed, self.pretrain_episodes)
        report(f"playing the rule-based LCA on {len(seeds)} demonstration episodes…")
        demos = collect_demonstrations(
            record.env_config, seeds, self.params.gamma, progress=self.progress
        )
        result = clone(
            self.model,
            demos,
            self.pretrain_epochs,
            seed=record.run.seed,
            seeds=seeds,
            masked=record.algorithm == "MaskablePPO",
        )
        self.record = replace(record, pretrain=result.record())
        self.write_record()
        self.clone_pending = False
        report(result.text())

    def _callbacks(self) -> list[Any]:
        """The training's callbacks, in this order: on a rollout boundary the
        checkpoint is written before validating."""
        from aldm_gym.training.sb3.callbacks import (
            ProgressCallback,
            RolloutCheckpointCallback,
            ValidationCallback,
        )

        record, run = self.record, self.record.run
        self.checkpointer = RolloutCheckpointCallback(run.checkpoint_freq, self.out)
        callbacks: list[Any] = [self.checkpointer]
        if run.validation_freq > 0 and run.validation_episodes > 0:
            callbacks.append(
                ValidationCallback(
                    self.out,
                    record.env_config,
                    run.validation_freq,
                    run.validation_episodes,
                    progress=self.progress,
                    validate_first=record.pretrain is not None and self.done == 0,
                    keep_by=record.keep_by or "return",
                )
            )
        if self.progress:
            callbacks.append(ProgressCallback(run.timesteps))
        if self.callback is not None:
            callbacks += self.callback if isinstance(self.callback, list) else [self.callback]
        return callbacks

    def learn(self, stop: StopRequest) -> None:
        """One ``model.learn`` to the budget (SB3's rollouts are the chunks; the first
        signal interrupts it at once, see :attr:`stops_at_once`), then the snapshot of
        the state after the last update. A new model to be cloned is cloned first."""
        if self.clone_pending:
            self._pretrain()
        callbacks = self._callbacks()
        if self.record.run.timesteps > self.done:
            self.model.learn(
                total_timesteps=self.record.run.timesteps - self.done,
                callback=callbacks,
                reset_num_timesteps=not self.resumed,
                tb_log_name=self.record.algorithm,
            )
        # The state after the last update (also when resumed with nothing left to do),
        # taken while the envs are open.
        self.final = take_snapshot(self.model)

    def save_checkpoint(self) -> CheckpointRef | None:
        """Write the snapshot of the last completed update (see
        :meth:`~aldm_gym.training.sb3.callbacks.RolloutCheckpointCallback.save_last_snapshot`)."""
        if self.checkpointer is None:
            return None
        path = self.checkpointer.save_last_snapshot()
        if path is None:
            return None
        return CheckpointRef(self.checkpointer.snapshot_steps, path)

    def save_final(self) -> Path:
        """The final snapshot as a checkpoint, ``model.zip`` and ``vecnormalize.pkl``."""
        assert self.final is not None and self.checkpointer is not None
        self.checkpointer.snapshot = self.final
        self.checkpointer.save_last_snapshot()
        write_bytes_atomic(self.out / MODEL_FILE, self.final.model)
        write_bytes_atomic(self.out / VECNORM_FILE, self.final.vecnormalize)
        return self.out / MODEL_FILE

    def close(self, interrupted: bool) -> None:
        """Close the envs (:func:`~aldm_gym.training.sb3.envs.close_envs`)."""
        if self.venv is not None:
            close_envs(self.venv, interrupted)

    @classmethod
    def load_policy(cls, path: Path) -> tuple[Any, TrainingRecord]:
        """A model ``.zip`` (:func:`aldm_gym.training.sb3.policy.load_policy`)."""
        from aldm_gym.training.sb3.policy import load_policy

        return load_policy(path)


def train(
    out: Path,
    *,
    algo: str = "ppo",
    detector: str = "aldm",
    marking_model: str = "per_dash",
    timesteps: int | None = None,
    n_envs: int | None = None,
    seed: int | None = None,
    checkpoint_freq: int | None = None,
    duration: float | None = None,
    vehicles_count: int | None = None,
    collision_reward: float | None = DEFAULT_COLLISION_REWARD,
    overtaking_reward: float | None = None,
    env_overrides: Mapping[str, Any] | None = None,
    params: PPOParams | None = None,
    validation_freq: int | None = None,
    validation_episodes: int | None = None,
    pretrain_episodes: int = 0,
    pretrain_epochs: int = DEFAULT_PRETRAIN_EPOCHS,
    keep_by: str | None = None,
    resume: bool = False,
    progress: bool = True,
    verbose: int = 0,
    callback: Any = None,
) -> Any:
    """Train (or resume training) a PPO policy; return the SB3 model.

    :param out: output folder (its files: :mod:`aldm_gym.training.outputs`); held
        locked while training.
    :param algo: ``"ppo"`` (stable-baselines3) or ``"maskable-ppo"`` (sb3-contrib's
        MaskablePPO: actions the env's ``action_masks()`` rules out are never sampled);
        a resume keeps the training's own.
    :param timesteps: total policy steps of the training (counting steps done before a
        resume), rounded up to whole rollouts (``n_steps × n_envs``); default
        :data:`~aldm_gym.training.settings.DEFAULT_TIMESTEPS`.
    :param n_envs: envs run in parallel (default 1).
    :param seed: seed of the envs (``seed + i`` for the i-th) and the network (0).
    :param checkpoint_freq: save a checkpoint every this many steps [policy steps]
        (default :data:`~aldm_gym.training.settings.DEFAULT_CHECKPOINT_FREQ`).
    :param duration, vehicles_count, collision_reward, overtaking_reward: env overrides
        (None: the env's defaults).
    :param env_overrides: any other env settings (sections merged key by key), e.g.
        ``{"detector_params": {"tracking": "model"}}``
        (:func:`~aldm_gym.training.settings.env_config`); saved in ``training.json``,
        so evaluation and resume build the same env.

    The defaults (one env, 49152 steps, collision weight -2, linearly decaying learning
    rate) are the recipe of ``docs/results.md`` (b). It is sensitive to the rollout size:
    two envs with the same or with halved rollouts missed the aim there.
    :param validation_freq: validate every this many steps (0: never) [policy steps]
        (default :data:`~aldm_gym.training.settings.DEFAULT_VALIDATION_FREQ`).
    :param validation_episodes: episodes per validation (seeds ``VALIDATION_SEED ..``;
        default :data:`~aldm_gym.training.settings.DEFAULT_VALIDATION_EPISODES`).
    :param pretrain_episodes: before PPO, clone the rule-based LCA played on this many
        episodes into the new model (0: no cloning;
        :mod:`~aldm_gym.training.sb3.pretrain`); with validation on, the clone is also
        validated at step 0. Not with ``resume``: a resume keeps the training's own
        (and clones again only if it restarts from step 0).
    :param pretrain_epochs: passes over the demonstrations.
    :param keep_by: the validation keeps as ``best_model.zip`` the model of the highest
        mean return (``"return"``, the default) or the highest score, mean speed less
        10 m/s per unit of failed-episode share
        (``"score"``, :func:`~aldm_gym.training.settings.validation_score`: the return
        mixes speed with the reward's other terms, and a validation with a collision
        can outscore one without). A resume keeps the training's own.
    :param progress: a tqdm bar over the steps, showing the recent training episodes'
        mean return and length, and one over each validation's episodes (the progress
        lines announcing and reporting each validation are logged either way).
    :param callback: extra SB3 callback(s) (a list or one).
    :param resume: continue from the newest intact checkpoint of ``out``; the env
        config and hyperparameters are those saved in ``<out>/training.json``, and so
        is every one of :data:`RUN_SETTINGS` left None (the settings restored and
        overridden are logged). With the saved ``n_envs`` and ``seed`` the envs and
        RNGs continue exactly where the checkpoint was taken.
    :raises FileExistsError: ``out`` holds a training and ``resume`` is False.
    :raises FileNotFoundError: ``resume`` without a ``training.json`` in ``out`` (one
        without an intact checkpoint starts again from step 0 with its settings).
    :raises ResumeError: ``resume`` of an RLlib training.
    :raises OutputLocked: another training is writing ``out``.
    :raises ConfigError: ``pretrain_episodes`` outside ``0..MAX_PRETRAIN_EPISODES``,
        ``pretrain_epochs`` < 1, ``pretrain_episodes`` with ``resume``, a ``keep_by``
        not in :data:`~aldm_gym.training.settings.KEEP_BY` or, on a resume, other than
        the training's.
    :raises MissingRLDependencies: stable-baselines3 / torch missing.
    :raises KeyboardInterrupt: interrupted by Ctrl-C or SIGTERM (after saving the
        last consistent state as a checkpoint).
    """
    check_pretrain(pretrain_episodes, pretrain_epochs)
    if keep_by is not None:
        check_keep_by(keep_by)
    if resume and pretrain_episodes:
        raise ConfigError(
            "pretrain_episodes clones before a new training only; a resume keeps the training's own"
        )
    backend = train_with(
        SB3Backend,
        out,
        given={
            "timesteps": timesteps,
            "n_envs": n_envs,
            "seed": seed,
            "checkpoint_freq": checkpoint_freq,
            "validation_freq": validation_freq,
            "validation_episodes": validation_episodes,
        },
        config=env_config(
            detector,
            marking_model,
            duration,
            vehicles_count,
            collision_reward,
            overtaking_reward,
            env_overrides,
        ),
        params=params,
        resume=resume,
        progress=progress,
        algorithm=algorithm_name(algo),
        verbose=verbose,
        callback=callback,
        pretrain_episodes=pretrain_episodes,
        pretrain_epochs=pretrain_epochs,
        keep_by=keep_by,
    )
    return backend.model
