"""Training PPO lane-change policies on ``ALDMHighway-v0``: ``aldm-gym train``/``evaluate``.

Two backends train the same task (env config, reward, hyperparameters) behind one
interface, :class:`~aldm_gym.training.backend.Backend`: stable-baselines3 on one
machine (:mod:`aldm_gym.training.sb3`) and Ray RLlib on a Ray cluster
(:mod:`aldm_gym.training.rllib`). Shared modules, one job each:

* :mod:`~aldm_gym.training.settings`: the env config, PPO hyperparameters and run
  settings of a training, and their defaults.
* :mod:`~aldm_gym.training.backend`: the backend interface and the training every
  backend runs through (:func:`~aldm_gym.training.backend.train_with`): lock, resume,
  fallback to an intact checkpoint, ``training.json``, signals.
* :mod:`~aldm_gym.training.outputs`: the output folder's files, atomic writes.
* :mod:`~aldm_gym.training.lock`: one writer per output folder.
* :mod:`~aldm_gym.training.signals`: SIGINT/SIGTERM stop a training at a safe point.
* :mod:`~aldm_gym.training.progress`: the progress bar and progress lines.
* :mod:`~aldm_gym.training.models`: the backends by name; any trained model as a policy.
* :mod:`~aldm_gym.training.model_evaluation`: a trained model against IDLE and the
  rule-based LCA, with a verdict that states its uncertainty.

Importing the package loads neither stable-baselines3, torch nor Ray (the ``[rl]`` and
``[ray]`` extras): they are imported when a training or an evaluation runs. Messages
go to :mod:`logging` (the command line prints them); warnings about the output folder
are :class:`~aldm_gym.errors.TrainingWarning`.
"""
