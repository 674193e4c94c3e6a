"""The patcher: :func:`use_fast_road` makes any highway-env env simulate on a FastRoad."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from aldm_gym.envs.traffic.road import FastRoad

if TYPE_CHECKING:
    from highway_env.envs.common.abstract import AbstractEnv

__all__ = ["use_fast_road"]


def use_fast_road(env: Any) -> AbstractEnv:
    """Make a highway-env environment simulate on a :class:`FastRoad`.

    The env's ``_create_road`` is wrapped (on the instance) so that every road it
    creates on ``reset`` is rewrapped with :meth:`FastRoad.from_road` before vehicles
    are added; the current road, if any, is converted too. Works through Gymnasium
    wrappers.

    :param env: a highway-env environment (``AbstractEnv``), possibly wrapped.
    :return: the unwrapped environment.
    """
    base = env.unwrapped
    if getattr(base, "_fast_road_installed", False):
        return base
    create_road = base._create_road

    def _create_fast_road() -> None:
        create_road()
        base.road = FastRoad.from_road(base.road)

    base._create_road = _create_fast_road
    base._fast_road_installed = True
    if base.road is not None:
        base.road = FastRoad.from_road(base.road)
    return base
