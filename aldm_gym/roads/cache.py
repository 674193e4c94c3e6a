"""Small caches of built roads, shared by environments across resets.

Building a road (a generated highway's curvature profile and tables, or a parsed
OpenDRIVE map) costs milliseconds to seconds; roads are immutable, so every env in a
process that asks for the same road gets the same object.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

from aldm_gym.roads.highway import HighwayRoad, RoadConfig

T = TypeVar("T")


class LRUCache(Generic[T]):
    """Objects by key, the least recently used dropped beyond ``size``.

    :param size: entries kept.
    """

    def __init__(self, size: int) -> None:
        self.size = int(size)
        self._items: OrderedDict[Hashable, T] = OrderedDict()

    def get(self, key: Hashable, build: Callable[[], T]) -> T:
        """The object of ``key``, built with ``build()`` on a miss."""
        got = self._items.get(key)
        if got is None:
            got = build()
            self._items[key] = got
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        else:
            self._items.move_to_end(key)
        return got


_ROADS: LRUCache[HighwayRoad] = LRUCache(8)


def cached_road(config: RoadConfig) -> HighwayRoad:
    """The :class:`HighwayRoad` of ``config``, built once per process (an LRU cache)."""
    return _ROADS.get(config, lambda: HighwayRoad(config))
