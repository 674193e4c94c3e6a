"""The official OSI bindings, imported once with a clear error when they are missing.

``osi-python`` (``osi3``: the protobuf messages) and ``asam-osi-utilities`` (trace
files: MCAP, binary ``.osi``) are the ``[osi]`` extra.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

from aldm_gym.errors import MissingOSIDependencies

INSTALL_HINT = 'pip install "aldm-gym[osi]"  (osi-python, asam-osi-utilities)'


class _Bindings:
    """Lazy access to the osi3 message classes the package uses."""

    _modules: dict[str, ModuleType] | None = None

    def _load(self) -> dict[str, ModuleType]:
        if self._modules is None:
            try:
                from osi3 import (
                    osi_common_pb2,
                    osi_detectedlane_pb2,
                    osi_detectedobject_pb2,
                    osi_groundtruth_pb2,
                    osi_lane_pb2,
                    osi_object_pb2,
                    osi_sensordata_pb2,
                    osi_sensorview_pb2,
                    osi_version_pb2,
                )
            except ImportError as exc:
                raise MissingOSIDependencies(
                    f"ASAM OSI needs the official bindings, which are not installed ({exc}); "
                    f"install them with: {INSTALL_HINT}"
                ) from exc
            _Bindings._modules = {
                "common": osi_common_pb2,
                "detectedlane": osi_detectedlane_pb2,
                "detectedobject": osi_detectedobject_pb2,
                "groundtruth": osi_groundtruth_pb2,
                "lane": osi_lane_pb2,
                "object": osi_object_pb2,
                "sensordata": osi_sensordata_pb2,
                "sensorview": osi_sensorview_pb2,
                "version": osi_version_pb2,
            }
        return self._modules

    def __getattr__(self, name: str) -> Any:
        mods = self._load()
        for mod in mods.values():
            if hasattr(mod, name):
                value = getattr(mod, name)
                setattr(self, name, value)  # found once, then a plain attribute
                return value
        raise AttributeError(name)


osi3 = _Bindings()
"""``osi3.SensorView``, ``osi3.LaneBoundary``, ... loaded on first use."""


def interface_version() -> tuple[int, int, int]:
    """The OSI version of the installed bindings (major, minor, patch)."""
    mods = osi3._load()
    opts = mods["version"].DESCRIPTOR.GetOptions()
    ext = mods["version"].current_interface_version
    v = opts.Extensions[ext]
    return int(v.version_major), int(v.version_minor), int(v.version_patch)
