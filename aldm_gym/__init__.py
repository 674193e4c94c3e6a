"""aldm-gym: highway driving on an emulated CarMaker line sensor with the ALDM.

Importing this package registers ``ALDMHighway-v0`` with Gymnasium. The import is
kept light: no pygame, matplotlib or torch is loaded until used.
"""

from __future__ import annotations

__version__ = "0.1.0"
__all__ = ["__version__"]
