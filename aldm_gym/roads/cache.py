"""A small cache of built roads, shared by environments across resets.

Building a :class:`~aldm_gym.roads.highway.HighwayRoad` (curvature profile, reference
line, marking tables) costs milliseconds to seconds; roads are immutable, so every
env in a process that asks for the same config gets the same object.
"""

from __future__ import annotations

from collections import OrderedDict

from aldm_gym.roads.highway import HighwayRoad, RoadConfig

CACHE_SIZE = 8
"""Roads kept (least recently used dropped first)."""

_CACHE: OrderedDict[RoadConfig, HighwayRoad] = OrderedDict()


def cached_road(config: RoadConfig) -> HighwayRoad:
    """The :class:`HighwayRoad` of ``config``, built once per process (an LRU cache)."""
    road = _CACHE.get(config)
    if road is None:
        road = HighwayRoad(config)
        _CACHE[config] = road
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    else:
        _CACHE.move_to_end(config)
    return road
