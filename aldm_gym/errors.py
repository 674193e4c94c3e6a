"""The exceptions and warnings aldm-gym raises on purpose, by kind.

A caller can tell a typo in a setting from a corrupt map or a broken checkpoint by the
class it catches. Every class also derives from the matching built-in exception
(``ValueError``, ``FileNotFoundError``, ``RuntimeError``, ``ImportError``), so code
that catches those catches these too::

    AldmGymError
    ├── ConfigError (ValueError)        an unknown setting or a value out of its rules
    ├── InputError (ValueError)         unusable data: wrong shape, NaN/inf, empty
    │   ├── OffRoadError                a world position on no lane of the road
    │   ├── ScenarioError               an OpenSCENARIO file that cannot be played
    │   └── TraceError                  an ASAM OSI trace that cannot be read
    ├── MapError (ValueError)           an OpenDRIVE file that cannot be read or used
    ├── MapNotFoundError (FileNotFoundError)
    ├── CheckpointError (ValueError)    a training output or checkpoint that cannot be used
    │   └── ResumeError                 ... cannot be resumed by this backend
    ├── ClusterError (ValueError)       no Ray cluster at the address, or too few CPUs
    ├── OutputLocked (RuntimeError)     another training holds the output folder
    ├── MissingRLDependencies (ImportError)
    │   └── MissingRayDependencies
    └── MissingOSIDependencies (ImportError)

    AldmGymWarning (UserWarning)
    ├── NumbaCacheWarning               a kernel's cache was unusable: recompiled
    ├── ScenarioWarning                 a scenario element with no meaning here: ignored
    └── TrainingWarning                 a training output was repaired or skipped

Messages name what is wrong: the setting and the allowed values, the file, road,
element and line of a map or a scenario, the argument to blame.
"""

from __future__ import annotations

__all__ = [
    "AldmGymError",
    "AldmGymWarning",
    "CheckpointError",
    "ClusterError",
    "ConfigError",
    "InputError",
    "MapError",
    "MapNotFoundError",
    "MissingOSIDependencies",
    "MissingRLDependencies",
    "MissingRayDependencies",
    "NotDrivenError",
    "NumbaCacheWarning",
    "OffRoadError",
    "OutputLocked",
    "ResumeError",
    "ScenarioError",
    "ScenarioWarning",
    "TraceError",
    "TrainingWarning",
]


class AldmGymError(Exception):
    """Base of every exception aldm-gym raises on purpose."""


class ConfigError(AldmGymError, ValueError):
    """A setting is unknown (the message names it, the allowed ones and the nearest
    match) or its value breaks the setting's rule (range, choices, type)."""


class InputError(AldmGymError, ValueError):
    """Data given to a function cannot be used: wrong shape or type, NaN or inf,
    an empty frame where points are needed, a pose outside the world."""


class OffRoadError(InputError):
    """A world position lies on no lane of the road (off a map's lanes)."""


class ScenarioError(InputError):
    """An OpenSCENARIO file (or a parameter given for it) that cannot be played: the
    message names the file, the line and the element (``file.xosc:57 <SpeedAction>``)."""


class TraceError(InputError):
    """An ASAM OSI trace (or message) that cannot be read or used: the message names
    the file and the frame (``run.mcap frame 17: no host vehicle``)."""


class MapError(AldmGymError, ValueError):
    """An OpenDRIVE file cannot be read or driven on: malformed XML, a record that
    cannot be evaluated, no driving lane (naming file, road, element and line)."""


class NotDrivenError(MapError):
    """A lane of the map exists there but is not a driving lane (a shoulder, a
    border): a place on it is a point beside the driving lanes."""


class MapNotFoundError(AldmGymError, FileNotFoundError):
    """The OpenDRIVE file does not exist (the message says where shipped maps are)."""


class CheckpointError(AldmGymError, ValueError):
    """A training output, model or checkpoint is missing, corrupt or incompatible."""


class ResumeError(CheckpointError):
    """What ``--resume`` found in the output folder cannot be resumed by this backend."""


class ClusterError(AldmGymError, ValueError):
    """No Ray cluster at the address, a token it refuses, or too few CPUs.

    :ivar argument: the command-line flag to blame (``--address`` or
        ``--num-env-runners``).
    """

    def __init__(self, message: str, argument: str = "--address") -> None:
        super().__init__(message)
        self.argument = argument


class OutputLocked(AldmGymError, RuntimeError):
    """Another training holds the output folder's lock."""


class MissingRLDependencies(AldmGymError, ImportError):
    """stable-baselines3, torch or Ray RLlib is not installed (the message says how)."""


class MissingRayDependencies(MissingRLDependencies):
    """Ray RLlib or torch is not installed (the ``[ray]`` extra)."""


class MissingOSIDependencies(AldmGymError, ImportError):
    """osi-python or asam-osi-utilities is not installed (the ``[osi]`` extra)."""


class MissingFMIDependencies(AldmGymError, ImportError):
    """fmpy or pythonfmu is not installed (the ``[fmi]`` extra)."""


class AldmGymWarning(UserWarning):
    """Base of the warnings aldm-gym issues."""


class NumbaCacheWarning(AldmGymWarning):
    """numba's cache of a kernel was unusable; the kernel was (re)compiled."""


class ScenarioWarning(AldmGymWarning):
    """A valid OpenSCENARIO element with no meaning on the env (weather, traffic
    signals, light states, ...) was ignored: one warning per element kind and file."""


class TrainingWarning(AldmGymWarning):
    """Something in a training's output folder was repaired or skipped (a stale lock,
    a corrupt checkpoint)."""
