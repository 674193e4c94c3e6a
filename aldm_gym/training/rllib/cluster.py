"""Where an RLlib training runs: a Ray instance of its own, or a running cluster."""

from __future__ import annotations

import logging
import os
import socket
import warnings
from typing import Any

from aldm_gym.errors import ClusterError

logger = logging.getLogger(__name__)

CONNECT_TIMEOUT = 5.0
"""Seconds to wait for a cluster's head at ``--address`` to accept a connection."""


def connect(address: str | None, num_env_runners: int) -> None:
    """Start a local Ray instance (``address`` None) or join a running cluster.

    A local instance is given at least one CPU per env runner (more runners than cores
    share them, with a warning).

    :raises ClusterError: no cluster answers at ``address``, it refuses this process
        (e.g. no or another auth token), or it has fewer CPUs than the env runners need
        (RLlib would wait for them forever).
    """
    import ray

    kwargs: dict[str, Any] = {"include_dashboard": False, "logging_level": "ERROR"}
    if address is None:  # "local": a new instance, even where a cluster is running
        cores = os.cpu_count() or 1
        if num_env_runners > cores:
            warnings.warn(
                f"{num_env_runners} env runners share {cores} cores", UserWarning, stacklevel=3
            )
        kwargs.update(address="local", num_cpus=max(cores, num_env_runners))
    else:
        if address != "auto":
            check_reachable(address)  # ray.init retries a dead address for minutes
        kwargs["address"] = address
    try:
        ray.init(**kwargs)
    except (ConnectionError, RuntimeError, ray.exceptions.RayError) as exc:
        raise ClusterError(
            f"cannot join the Ray cluster at {address!r} ({exc}); a cluster with token "
            "authentication needs RAY_AUTH_MODE=token and its token here (docs/cluster.md)"
        ) from None
    cpus = float(ray.cluster_resources().get("CPU", 0))
    if cpus < num_env_runners:
        ray.shutdown()
        raise ClusterError(
            f"the Ray cluster at {address or 'local'} has {cpus:g} CPUs; "
            f"{num_env_runners} env runners need one each",
            argument="--num-env-runners",
        )
    where = f"the Ray cluster at {address}" if address else "a local Ray instance"
    logger.info("training on %s (%g CPUs)", where, cpus)


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """Raise :class:`~aldm_gym.errors.ClusterError` unless something accepts TCP
    connections at ``host:port``."""
    host, _, port = address.rpartition(":")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            pass
    except (OSError, ValueError) as exc:
        raise ClusterError(
            f"no Ray cluster answers at {address} ({exc}); check the address, or start "
            f"a cluster there (docs/cluster.md)"
        ) from None
