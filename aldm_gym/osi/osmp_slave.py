"""The OSMP sensor model's FMI 2.0 slave (pythonfmu): the variables OSMP names, the
model built at initialisation from the FMU's parameters, one SensorView per step.

The FMU's script (written by :func:`aldm_gym.osi.osmp.build_sensor_fmu`) declares
``class <Model>(Fmi2Slave)`` itself, as pythonfmu's runtime looks for that line, and
hands its work to :func:`setup`, :func:`initialize` and :func:`step`. It runs inside
the host's process and needs pythonfmu (the ``[fmi]`` extra).
"""

from __future__ import annotations

import json
from typing import Any

from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Variability, Integer, String
from pythonfmu.enums import Fmi2Status

from aldm_gym.osi.osmp import DATA_OUT, ROLES, VIEW_IN, OSMPSensorModel

__all__ = ["PARAMETERS", "initialize", "setup", "step"]

PARAMETERS = ("detector", "tracking", "marking_model", "settings")
"""The FMU's string parameters (fixed after initialisation); ``seed`` is an integer one."""


def setup(slave: Any, defaults: dict[str, str]) -> None:
    """Register OSMP's variables and the parameters on a pythonfmu ``Fmi2Slave``.

    Parameters: the strings ``detector``, ``tracking``, ``marking_model``, ``settings``
    (JSON of the env's ``sensor`` and ``detector_params`` sections) starting at
    ``defaults``, and the integer ``seed`` (a noisy sensor's draws). Inputs:
    ``OSMPSensorViewIn.base.lo``, ``.base.hi``, ``.size``. Outputs:
    ``OSMPSensorDataOut.base.lo``, ``.base.hi``, ``.size`` and ``OSMPValid`` (false,
    with a warning logged, when a step's SensorView cannot be used).
    """
    for name in PARAMETERS:
        setattr(slave, name, defaults[name])
    slave.seed = 0
    slave.view = [0, 0, 0]
    slave.data = [0, 0, 0]
    slave.valid = False
    slave.model = None
    for name in PARAMETERS:
        slave.register_variable(
            String(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        )
    slave.register_variable(
        Integer("seed", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
    )
    for k, role in enumerate(ROLES):
        slave.register_variable(
            Integer(
                f"{VIEW_IN}.{role}",
                causality=Fmi2Causality.input,
                variability=Fmi2Variability.discrete,
                getter=lambda k=k: slave.view[k],
                setter=lambda v, k=k: slave.view.__setitem__(k, int(v)),
            )
        )
    for k, role in enumerate(ROLES):
        slave.register_variable(
            Integer(
                f"{DATA_OUT}.{role}",
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.discrete,
                initial=Fmi2Initial.exact,
                getter=lambda k=k: slave.data[k],
            )
        )
    slave.register_variable(
        Boolean(
            "OSMPValid",
            causality=Fmi2Causality.output,
            variability=Fmi2Variability.discrete,
            initial=Fmi2Initial.exact,
            getter=lambda: slave.valid,
        )
    )


def initialize(slave: Any) -> None:
    """Build the model from the slave's parameters (``exit_initialization_mode``)."""
    slave.model = OSMPSensorModel(
        slave.detector,
        slave.tracking,
        slave.marking_model,
        json.loads(slave.settings or "{}"),
        seed=int(slave.seed),
    )


def step(slave: Any) -> bool:
    """Detect on the SensorView at ``OSMPSensorViewIn`` (``do_step``); the SensorData
    at ``OSMPSensorDataOut`` stays valid until the start of the step after the next."""
    if slave.model is None:
        initialize(slave)
    lo, hi, size = slave.model.step(*slave.view)
    slave.data = [lo, hi, size]
    slave.valid = size > 0
    if not slave.valid:
        slave.log(slave.model.error, Fmi2Status.warning)
    return True
