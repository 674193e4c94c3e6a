"""The line sensor and a detector as an OSI Sensor Model Package (OSMP): an FMI 2.0
co-simulation FMU that takes ``osi3.SensorView`` and gives ``osi3.SensorData``.

OSMP passes each message as a binary variable: three FMI integers, the low and high 32
bits of a pointer to the serialized message and its size
(``OSMPSensorViewIn.base.lo``, ``.base.hi``, ``.size``). The host keeps its input
buffer valid during ``fmi2DoStep``; the FMU keeps its output buffer valid until the
start of the second ``fmi2DoStep`` after the one that produced it
(:class:`OSMPSensorModel`). The model itself is
:class:`~aldm_gym.osi.detect.OsiLaneSensor`, so the FMU's output is, message for
message, what ``aldm-gym osi detect`` writes.

:func:`build_sensor_fmu` (``aldm-gym osi fmu``) packages it with pythonfmu and adds the
OSMP annotations to ``modelDescription.xml``. The FMU runs the Python it is loaded
into, or the one its binary finds: aldm-gym and osi-python must be installed there
(docs/osi.md, "The ALDM as an OSMP FMU").
"""

from __future__ import annotations

import ctypes
import json
import shutil
import tempfile
import uuid
import zipfile
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any

from aldm_gym.errors import ConfigError, TraceError
from aldm_gym.fmi import Instance, import_fmpy

__all__ = [
    "OSMP_VERSION",
    "TRACKING_MODES",
    "OSMPHost",
    "OSMPSensorModel",
    "build_sensor_fmu",
    "detector_params_for",
    "pack_pointer",
    "unpack_pointer",
]

OSMP_VERSION = "1.5.0"
"""The OSI Sensor Model Packaging version the FMU follows."""

TRACKING_MODES = ("none", "points", "model")
"""``--tracking``: the single-frame detector, the tracking ALDM (points carried over
frames), or the lane-model filter."""

DEFAULT_STEP = 0.1
"""The FMU's default experiment step size [s] (OSMP asks for one; the model reads the
time from each SensorView's timestamp, so any step the host takes works)."""

MAX_MESSAGE_BYTES = 1 << 30
"""The largest SensorView read from a host's pointer [bytes]: a size beyond it is a
host's error, not a message."""

VIEW_IN = "OSMPSensorViewIn"
DATA_OUT = "OSMPSensorDataOut"
ROLES = ("base.lo", "base.hi", "size")


def pack_pointer(address: int) -> tuple[int, int]:
    """A 64-bit address as OSMP's two signed 32-bit FMI integers ``(lo, hi)``."""

    def signed(v: int) -> int:
        return v - (1 << 32) if v >= 1 << 31 else v

    return signed(address & 0xFFFFFFFF), signed((address >> 32) & 0xFFFFFFFF)


def unpack_pointer(lo: int, hi: int) -> int:
    """The address two OSMP integers ``(lo, hi)`` hold."""
    return ((int(hi) & 0xFFFFFFFF) << 32) | (int(lo) & 0xFFFFFFFF)


def detector_params_for(tracking: str, params: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The env's ``detector_params`` for a :data:`TRACKING_MODES` name and more params.

    :raises ConfigError: an unknown mode.
    """
    if tracking not in TRACKING_MODES:
        raise ConfigError(f"tracking must be one of {list(TRACKING_MODES)}, got {tracking!r}")
    out = dict(params or {})
    if tracking != "none":
        out["tracking"] = True if tracking == "points" else "model"
    return out


class OSMPSensorModel:
    """The OSMP side of the sensor model: a SensorView buffer in, a SensorData buffer
    out, the tracker's state carried between steps.

    :param detector: ``"aldm"`` or ``"naive"``.
    :param tracking: one of :data:`TRACKING_MODES`.
    :param marking_model: ``"per_dash"`` or ``"editor"``.
    :param settings: ``{"sensor": {...}, "detector_params": {...}}`` (the env's sections).
    :param seed: seed of a noisy sensor's draws (as ``osi detect --seed``).
    :raises ConfigError: a bad setting (named).
    """

    def __init__(
        self,
        detector: str = "aldm",
        tracking: str = "none",
        marking_model: str = "per_dash",
        settings: Mapping[str, Any] | None = None,
        seed: int = 0,
    ) -> None:
        from aldm_gym.osi.detect import OsiLaneSensor

        settings = dict(settings or {})
        unknown = sorted(set(settings) - {"sensor", "detector_params"})
        if unknown:
            raise ConfigError(
                f"settings: unknown section(s) {unknown}; allowed: ['detector_params', 'sensor']"
            )
        params = detector_params_for(tracking, settings.get("detector_params"))
        self.model = OsiLaneSensor(
            detector,
            params,
            marking_model,
            settings.get("sensor"),
            source="OSMPSensorViewIn",
            seed=seed,
        )
        self._out: ctypes.Array[ctypes.c_char] | None = None
        self._previous: ctypes.Array[ctypes.c_char] | None = None
        self.error = ""
        """Why the last step gave no output ("" after a good one)."""

    def step(self, lo: int, hi: int, size: int) -> tuple[int, int, int]:
        """One SensorView at ``(lo, hi, size)`` in, the SensorData's ``(lo, hi, size)``
        out; ``(0, 0, 0)`` and :attr:`error` set when the input cannot be used (no
        message, a size out of range, a message that does not parse or that the line
        sensor cannot read). The output buffer stays valid until the call after the
        next one returns (OSMP's rule for ``doStep``)."""
        from aldm_gym.osi._bindings import osi3

        # OSMP: an output stays valid until the start of the second doStep after the one
        # that produced it; the one before it can go now.
        self._previous, self._out = self._out, None
        if size <= 0 or size > MAX_MESSAGE_BYTES or unpack_pointer(lo, hi) == 0:
            self.error = f"no SensorView (pointer {unpack_pointer(lo, hi):#x}, size {size})"
            return 0, 0, 0
        raw = ctypes.string_at(unpack_pointer(lo, hi), size)
        view = osi3.SensorView()
        try:
            view.ParseFromString(raw)
            data = self.model.step(view).SerializeToString()
        except TraceError as exc:
            self.error = str(exc)
            return 0, 0, 0
        except Exception as exc:  # protobuf's DecodeError and kin: a corrupt buffer
            self.error = f"the SensorView does not parse: {exc}"
            return 0, 0, 0
        self.error = ""
        self._out = ctypes.create_string_buffer(data, len(data))
        out_lo, out_hi = pack_pointer(ctypes.addressof(self._out))
        return out_lo, out_hi, len(data)


SLAVE_TEMPLATE = '''"""aldm-gym's line sensor and {detector} as an OSMP sensor model (generated by
``aldm-gym osi fmu``)."""

from pythonfmu import Fmi2Slave
from pythonfmu.default_experiment import DefaultExperiment

from aldm_gym.osi import osmp_slave

DEFAULTS = {defaults!r}


class {name}(Fmi2Slave):
    """The FMU's model (:mod:`aldm_gym.osi.osmp_slave`); parameters start at DEFAULTS."""

    author = "aldm-gym"
    description = "CarMaker line sensor + {detector} (OSMP sensor model)"
    default_experiment = DefaultExperiment(start_time=0.0, step_size={step_size!r})

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        osmp_slave.setup(self, DEFAULTS)

    def exit_initialization_mode(self):
        osmp_slave.initialize(self)

    def do_step(self, current_time, step_size):
        return osmp_slave.step(self)
'''


def _osi_version() -> str:
    try:
        return metadata.version("osi-python")
    except metadata.PackageNotFoundError:  # pragma: no cover - the [osi] extra is needed
        return "3"


def _annotate(model_description: bytes) -> bytes:
    """``modelDescription.xml`` with OSMP's ``net.pmsf.osmp`` annotations: the package
    (OSMP and OSI versions) and each binary variable's name, role and MIME type."""
    from lxml import etree

    ns = "http://xsd.pmsf.net/OSISensorModelPackaging"
    root = etree.fromstring(model_description)
    osi = _osi_version()
    vendor = root.find("VendorAnnotations")
    if vendor is None:
        vendor = etree.Element("VendorAnnotations")
        anchor = root.find("ModelVariables")
        anchor.addprevious(vendor)
    tool = etree.SubElement(vendor, "Tool", name="net.pmsf.osmp", nsmap={"osmp": ns})
    etree.SubElement(tool, f"{{{ns}}}osmp", version=OSMP_VERSION, **{"osi-version": osi})
    kinds = {VIEW_IN: "SensorView", DATA_OUT: "SensorData"}
    for var in root.find("ModelVariables"):
        name, _, role = var.get("name", "").partition(".")
        if name not in kinds or role not in ROLES:
            continue
        annotations = etree.SubElement(var, "Annotations")  # after the type element
        t = etree.SubElement(annotations, "Tool", name="net.pmsf.osmp", nsmap={"osmp": ns})
        etree.SubElement(
            t,
            f"{{{ns}}}osmp-binary-variable",
            name=name,
            role=role,
            **{
                "mime-type": f"application/x-open-simulation-interface; type={kinds[name]}; "
                f"version={osi}"
            },
        )
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def build_sensor_fmu(
    out: str | Path,
    *,
    detector: str = "aldm",
    tracking: str = "none",
    marking_model: str = "per_dash",
    sensor: Mapping[str, Any] | None = None,
    detector_params: Mapping[str, Any] | None = None,
) -> Path:
    """Write an OSMP sensor-model FMU (FMI 2.0 co-simulation) of the line sensor and a
    detector. Its parameters (``detector``, ``tracking``, ``marking_model``,
    ``settings``: JSON of the ``sensor`` and ``detector_params`` sections) start at
    these values and can be set by the host before initialisation.

    :param out: the ``.fmu`` to write; its stem (made a Python identifier) is the
        model identifier.
    :raises ConfigError: a setting the model refuses (checked before packaging).
    :raises MissingFMIDependencies: pythonfmu missing (the ``[fmi]`` extra).
    """
    try:
        from pythonfmu import FmuBuilder
    except ImportError:
        from aldm_gym.errors import MissingFMIDependencies

        raise MissingFMIDependencies(
            "building an FMU needs pythonfmu: pip install 'aldm-gym[fmi]'"
        ) from None
    out = Path(out)
    settings: dict[str, Any] = {}
    if sensor:
        settings["sensor"] = dict(sensor)
    if detector_params:
        settings["detector_params"] = dict(detector_params)
    OSMPSensorModel(detector, tracking, marking_model, settings)  # refuse bad settings now
    name = "".join(c if c.isalnum() else "_" for c in out.stem)
    if not name or name[0].isdigit():
        name = f"ALDM_{name}"
    with tempfile.TemporaryDirectory(prefix="aldm_osmp_") as tmp:
        # a module name of its own: an FMU's runtime imports its script into the host's
        # interpreter, where another FMU's (or an earlier build's) must not shadow it
        script = Path(tmp) / f"{name}_{uuid.uuid4().hex[:12]}.py"
        script.write_text(
            SLAVE_TEMPLATE.format(
                name=name,
                detector=detector,
                step_size=DEFAULT_STEP,
                defaults={
                    "detector": detector,
                    "tracking": tracking,
                    "marking_model": marking_model,
                    "settings": json.dumps(settings, sort_keys=True),
                },
            )
        )
        built = Path(FmuBuilder.build_FMU(script, dest=Path(tmp) / "fmu"))
        annotated = Path(tmp) / "annotated.fmu"
        with zipfile.ZipFile(built) as src, zipfile.ZipFile(annotated, "w") as dst:
            for item in src.infolist():
                data = src.read(item.filename)
                if item.filename == "modelDescription.xml":
                    data = _annotate(data)
                dst.writestr(item, data, compress_type=zipfile.ZIP_DEFLATED)
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(annotated), out)
    return out


class OSMPHost:
    """A minimal OSMP co-simulation host for a sensor-model FMU (fmpy): SensorView
    bytes in, SensorData bytes out, buffers passed by pointer as OSMP prescribes.

    :param fmu: the ``.fmu``.
    :param parameters: parameters to set before initialisation (e.g.
        ``{"tracking": "model", "seed": 3}``: strings, or integers).
    :param step_size: the communication step [s].
    :raises MissingFMIDependencies: fmpy missing.
    """

    def __init__(
        self,
        fmu: str | Path,
        parameters: Mapping[str, str | int] | None = None,
        step_size: float = 0.1,
    ) -> None:
        md = import_fmpy().read_model_description(str(fmu))
        self.refs = {v.name: v.valueReference for v in md.modelVariables}
        self.parameters = dict(parameters or {})
        self.step_size = step_size
        self.time = 0.0
        self._input: ctypes.Array[ctypes.c_char] | None = None
        self.instance = Instance(fmu, md, "osmp_sensor", self._set_parameters)
        self.fmu = self.instance.fmu

    def _set_parameters(self, fmu: Any) -> None:
        for name, value in self.parameters.items():
            if isinstance(value, int):
                fmu.setInteger([self.refs[name]], [value])
            else:
                fmu.setString([self.refs[name]], [value])

    def reset(self) -> None:
        """``fmi2Reset``, then initialise again with the same parameters."""
        self.instance.reset()
        self.time = 0.0

    def step(self, view: bytes) -> bytes | None:
        """One SensorView in, its SensorData out (None where ``OSMPValid`` is false)."""
        fmu, refs = self.fmu, self.refs
        self._input = ctypes.create_string_buffer(view, len(view))
        lo, hi = pack_pointer(ctypes.addressof(self._input))
        names = [f"{VIEW_IN}.{role}" for role in ROLES]
        fmu.setInteger([refs[n] for n in names], [lo, hi, len(view)])
        fmu.doStep(self.time, self.step_size)
        self.time += self.step_size
        out = fmu.getInteger([refs[f"{DATA_OUT}.{role}"] for role in ROLES])
        if not fmu.getBoolean([refs["OSMPValid"]])[0]:
            return None
        return ctypes.string_at(unpack_pointer(out[0], out[1]), out[2])

    def close(self) -> None:
        """Terminate and free the instance."""
        self.instance.close()
