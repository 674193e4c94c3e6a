"""The gate to stable-baselines3: import it (and torch), or say how to install them.

stable-baselines3 and torch are optional (the ``[rl]`` extra) and heavy; modules that
need them import them inside functions through :func:`import_sb3`, so that
``import aldm_gym`` and the ``aldm-gym`` parser stay light.
"""

from __future__ import annotations

from typing import Any

from aldm_gym.errors import MissingRLDependencies


def import_sb3() -> Any:
    """Import stable_baselines3 (and torch) or raise :class:`MissingRLDependencies`."""
    try:
        import stable_baselines3
        import torch  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise MissingRLDependencies(
            f"training needs stable-baselines3, torch and tensorboard ({exc}); "
            "install them with: pip install torch==2.13.0 && pip install -e '.[rl]' (from a clone)"
        ) from exc
    return stable_baselines3
