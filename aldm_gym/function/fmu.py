"""A function under test in an FMU (FMI 2.0 or 3.0 co-simulation), run with fmpy.

The FMU's inputs and outputs are matched by name (FMI's structured naming, SI units,
sensor frame of ISO 8855). It declares the inputs it reads and the outputs it writes;
each name must be one of these (a mistyped name is an error that lists them):

==========================================  ======  =========================================
input                                       unit    meaning
==========================================  ======  =========================================
``ego.speed``                               m/s     the ego's speed
``ego.yaw_rate``                            rad/s   > 0 turning left
``ego.acceleration``                        m/s²    the last step's acceleration
``ego.steering``                            rad     the last step's steering angle, > 0 left
``ego.lane_change``                         --      the built-in lane change under way: +1/-1/0
``horizon.lane_end.valid``                  --      1 where the map horizon has a lane end
``horizon.lane_end.distance``               m       to where the ego's lane gets too narrow
``horizon.lane_end.side``                   --      the side to leave it by: +1/-1, 0 none
``line.<role>.valid``                       --      1 where the detector found the line
``line.<role>.c0`` .. ``c3``                m, --,  ``y(x) = c0 + c1 x + c2 x² + c3 x³``
                                            1/m,
                                            1/m²
``line.<role>.range``                       m       the line's farthest x
``line.<role>.confidence``                  --      the detector's confidence in [0, 1]
``object.count``                            --      objects reported (at most the FMU's slots)
``object[<i>].x``, ``.y``                   m       centre of the i-th nearest object
``object[<i>].vx``                          m/s     its speed relative to the ego
``object[<i>].vy``                          m/s     its lateral speed relative to the ego
``object[<i>].length``, ``.width``          m       its size
``object[<i>].valid``                       --      1 where slot i holds an object
==========================================  ======  =========================================

``<role>`` is ``left_adjacent``, ``ego_left``, ``ego_right`` or ``right_adjacent``;
``<i>`` counts from 0, and the FMU's slots are the ``object[i].x`` inputs it declares.

==========================================  ======  =========================================
output                                      unit    meaning
==========================================  ======  =========================================
``acceleration``                            m/s²    the longitudinal request
``steering``                                rad     the steering request, > 0 left ...
``curvature``                               1/m     ... or the path's curvature (not both)
``lane_change``                             --      +1 / -1: ask the built-in lane change
``speed_step``                              --      +1 / -1: the ACC's next set speed
==========================================  ======  =========================================

The domains follow from the outputs: ``steering`` or ``curvature`` take the lateral
domain, ``acceleration`` the longitudinal one. Real, integer and Boolean variables are
all accepted (integers and Booleans are rounded on the way in). The FMU is stepped
once per env step: inputs set, ``doStep`` over the env step (``1 / policy_frequency``,
whatever the FMU's default experiment says), outputs read as the requests for the
next step.
"""

from __future__ import annotations

import difflib
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.fmi import Instance, import_fmpy
from aldm_gym.function.interface import LINE_ROLES, FunctionInput, FunctionOutput

__all__ = ["INPUTS", "OUTPUTS", "FMUFunction"]

EGO_INPUTS = ("ego.speed", "ego.yaw_rate", "ego.acceleration", "ego.steering", "ego.lane_change")
HORIZON_INPUTS = ("horizon.lane_end.valid", "horizon.lane_end.distance", "horizon.lane_end.side")
LINE_FIELDS = ("valid", "c0", "c1", "c2", "c3", "range", "confidence")
OBJECT_FIELDS = ("x", "y", "vx", "vy", "length", "width", "valid")
INPUTS: tuple[str, ...] = (
    *EGO_INPUTS,
    *HORIZON_INPUTS,
    *(f"line.{role}.{f}" for role in LINE_ROLES for f in LINE_FIELDS),
    "object.count",
    *(f"object[<i>].{f}" for f in OBJECT_FIELDS),
)
"""The input names an FMU may declare (``<i>``: an object slot, from 0)."""

OUTPUTS = ("acceleration", "steering", "curvature", "lane_change", "speed_step")
"""The output names an FMU may declare."""

_OBJECT = re.compile(r"^object\[(\d+)\]\.(\w+)$")
MAX_OBJECT_SLOTS = 256
"""More object slots than a function has any use for: an FMU declaring more is refused."""


def _input_known(name: str) -> bool:
    m = _OBJECT.match(name)
    if m:
        return m.group(2) in OBJECT_FIELDS and int(m.group(1)) < MAX_OBJECT_SLOTS
    return name in INPUTS


def _listing(md: Any) -> str:
    """What an FMU declares: its inputs and outputs by name."""
    has = {c: [v.name for v in md.modelVariables if v.causality == c] for c in ("input", "output")}
    return f"the FMU has inputs {has['input'] or 'none'} and outputs {has['output'] or 'none'}"


def _unknown(kind: str, name: str, allowed: tuple[str, ...], path: Path, md: Any) -> InputError:
    near = difflib.get_close_matches(name, allowed, n=1)
    hint = f" (did you mean {near[0]!r}?)" if near else ""
    return InputError(
        f"{path.name}: {kind} {name!r} is not in aldm-gym's convention{hint}; "
        f"{kind}s: {', '.join(allowed)} (docs/api.md, 'Functions in an FMU'); "
        f"{_listing(md)}"
    )


class FMUFunction:
    """A co-simulation FMU (FMI 2.0 or 3.0) as a function under test.

    :param path: the ``.fmu``.
    :param instance_name: the FMU instance's name.
    :raises MissingFMIDependencies: fmpy missing (the ``[fmi]`` extra).
    :raises InputError: not a readable FMU, no co-simulation interface, an input or
        output outside the convention (named, with the nearest allowed name), or no
        output at all.
    """

    def __init__(self, path: str | Path, instance_name: str = "function") -> None:
        fmpy = import_fmpy()
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError(f"no FMU at {self.path}")
        try:
            md = fmpy.read_model_description(str(self.path), validate=True)
        except Exception as exc:  # fmpy raises plain Exceptions on a broken archive
            raise InputError(f"{self.path.name} is not a readable FMU: {exc}") from None
        if md.coSimulation is None:
            raise InputError(f"{self.path.name} has no co-simulation interface (FMI CS needed)")
        if md.fmiVersion not in ("2.0", "3.0"):
            raise InputError(f"{self.path.name}: FMI {md.fmiVersion} (2.0 or 3.0 are read)")
        self.model_description = md
        self.fmi_version = md.fmiVersion
        self.inputs: dict[str, Any] = {}
        self.outputs: dict[str, Any] = {}
        for v in md.modelVariables:
            if v.causality == "input":
                if not _input_known(v.name):
                    raise _unknown("input", v.name, INPUTS, self.path, md)
                self.inputs[v.name] = v
            elif v.causality == "output":
                if v.name not in OUTPUTS:
                    raise _unknown("output", v.name, OUTPUTS, self.path, md)
                self.outputs[v.name] = v
        if not self.outputs:
            raise InputError(
                f"{self.path.name} has no output of the convention; it needs one of "
                f"{', '.join(OUTPUTS)}; {_listing(md)}"
            )
        if "steering" in self.outputs and "curvature" in self.outputs:
            raise InputError(f"{self.path.name} outputs steering and curvature; give one")
        self.slots = sorted(
            {int(m.group(1)) for n in self.inputs if (m := _OBJECT.match(n)) is not None}
        )
        lateral = "steering" in self.outputs or "curvature" in self.outputs
        longitudinal = "acceleration" in self.outputs
        self.domains = frozenset(
            d for d, on in (("lateral", lateral), ("longitudinal", longitudinal)) if on
        )
        self.instance_name = instance_name
        self._instance: Instance | None = None
        self._fmu: Any = None
        self._time = 0.0

    # ------------------------------------------------------------------ lifecycle
    def reset(self) -> None:
        """A fresh start at time 0 (``fmi2Reset`` / ``fmi3Reset`` after the first
        episode)."""
        if self._instance is None:
            self._instance = Instance(self.path, self.model_description, self.instance_name)
        else:
            self._instance.reset()
        self._fmu = self._instance.fmu
        self._time = 0.0

    def close(self) -> None:
        """Terminate and free the instance; remove the extracted files."""
        if self._instance is not None:
            self._instance.close()
            self._instance = None
            self._fmu = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # nothing to report to at interpreter exit
            pass

    # ------------------------------------------------------------------ values
    def _set(self, variable: Any, value: float) -> None:
        fmu, vr, kind = self._fmu, [variable.valueReference], variable.type
        if kind in ("Real", "Float64"):
            fmu.setReal(vr, [value]) if self.fmi_version == "2.0" else fmu.setFloat64(vr, [value])
        elif kind == "Float32":
            fmu.setFloat32(vr, [value])
        elif kind == "Boolean":
            fmu.setBoolean(vr, [bool(round(value))])
        elif kind in ("Integer", "Int32"):
            v = round(value)
            fmu.setInteger(vr, [v]) if self.fmi_version == "2.0" else fmu.setInt32(vr, [v])
        else:
            raise InputError(f"{self.path.name}: input {variable.name} of type {kind} is not read")

    def _get(self, variable: Any) -> float:
        fmu, vr, kind = self._fmu, [variable.valueReference], variable.type
        if kind in ("Real", "Float64"):
            got = fmu.getReal(vr) if self.fmi_version == "2.0" else fmu.getFloat64(vr)
        elif kind == "Float32":
            got = fmu.getFloat32(vr)
        elif kind == "Boolean":
            got = fmu.getBoolean(vr)
        elif kind in ("Integer", "Int32"):
            got = fmu.getInteger(vr) if self.fmi_version == "2.0" else fmu.getInt32(vr)
        else:
            raise InputError(f"{self.path.name}: output {variable.name} of type {kind} is not read")
        return float(got[0])

    def values(self, inputs: FunctionInput) -> dict[str, float]:
        """Every input of the convention the FMU declares, with this step's value."""
        ego = inputs.ego
        out: dict[str, float] = {
            "ego.speed": ego.speed,
            "ego.yaw_rate": ego.yaw_rate,
            "ego.acceleration": ego.acceleration,
            "ego.steering": ego.steering,
            "ego.lane_change": float(inputs.lane_change),
        }
        ends = math.isfinite(inputs.lane_end_distance)
        out["horizon.lane_end.valid"] = float(ends)
        out["horizon.lane_end.distance"] = inputs.lane_end_distance if ends else 0.0
        out["horizon.lane_end.side"] = float(inputs.lane_end_side)
        for line in inputs.lines:
            prefix = f"line.{line.role}."
            c = line.cubic()
            out[prefix + "valid"] = float(line.found)
            for k in range(4):
                out[f"{prefix}c{k}"] = float(c[k])
            out[prefix + "range"] = line.range
            confidence = line.confidence if line.confidence is not None else float(line.found)
            out[prefix + "confidence"] = confidence
        nearest = sorted(inputs.objects, key=lambda o: float(np.hypot(o.x, o.y)))
        out["object.count"] = float(min(len(nearest), len(self.slots)))
        for k, slot in enumerate(self.slots):
            obj = nearest[k] if k < len(nearest) else None
            for f in OBJECT_FIELDS:
                name = f"object[{slot}].{f}"
                if f == "valid":
                    out[name] = float(obj is not None)
                else:
                    out[name] = 0.0 if obj is None else float(getattr(obj, f))
        return {name: value for name, value in out.items() if name in self.inputs}

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        """Set the inputs, ``doStep`` over ``inputs.step``, read the requests.

        :raises InputError: the FMU fails its step, or returns a value that is not
            finite.
        """
        if self._fmu is None:
            self.reset()
        for name, value in self.values(inputs).items():
            self._set(self.inputs[name], value)
        try:
            self._fmu.doStep(self._time, inputs.step)
        except Exception as exc:  # fmpy raises on a status other than OK
            raise InputError(
                f"{self.path.name}: doStep at {self._time:g} s failed: {exc}"
            ) from None
        self._time += inputs.step
        got = {name: self._get(v) for name, v in self.outputs.items()}
        for name, value in got.items():
            if not np.isfinite(value):
                raise InputError(f"{self.path.name}: output {name} is {value} at {self._time:g} s")
        return FunctionOutput(
            acceleration=got.get("acceleration"),
            steering=got.get("steering"),
            curvature=got.get("curvature"),
            lane_change=int(np.sign(round(got.get("lane_change", 0.0)))),
            speed_step=int(np.sign(round(got.get("speed_step", 0.0)))),
        )
