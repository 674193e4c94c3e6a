"""OSI trace files, per the OSI trace-file specification, through ``asam-osi-utilities``.

* **MCAP** (``.mcap``): one file, one channel per message type (topics ``SensorView``
  and ``SensorData``), the required ``net.asam.osi.trace`` file metadata and the
  channels' OSI and protobuf versions.
* **Binary** (``.osi``): one message type per file, each message prefixed with its
  length (4 bytes, little endian). Two message types go to two files named after the
  OSI naming convention's type codes: ``run.osi`` -> ``run_sv.osi`` and ``run_sd.osi``.

:func:`read_messages` reads ``SensorView`` or ``GroundTruth`` messages from either
kind; every error names the file (and the frame where it is known).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from aldm_gym.errors import InputError, TraceError
from aldm_gym.osi._bindings import interface_version, osi3

SUFFIXES = (".mcap", ".osi")
"""Trace file kinds read and written."""

SHORT_CODE = {"SensorView": "sv", "SensorData": "sd", "GroundTruth": "gt"}
"""The OSI naming convention's code of each message type (binary traces)."""

INPUT_TYPES = ("SensorView", "GroundTruth")
"""Message types :func:`read_messages` turns into frames, preferred first."""


def _utilities() -> Any:
    from aldm_gym.errors import MissingOSIDependencies
    from aldm_gym.osi._bindings import INSTALL_HINT

    try:
        import osi_utilities
    except ImportError as exc:
        raise MissingOSIDependencies(
            f"OSI trace files need asam-osi-utilities ({exc}); install it with: {INSTALL_HINT}"
        ) from exc
    return osi_utilities


def _check_suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(
            f"{path}: an OSI trace must end in one of {list(SUFFIXES)}, got {path.suffix!r}"
        )
    return suffix


def binary_path(path: Path, message_type: str) -> Path:
    """The ``.osi`` file of one message type of a trace named ``path``."""
    return path.with_name(f"{path.stem}_{SHORT_CODE[message_type]}{path.suffix}")


class TraceWriter:
    """Writes OSI messages to a trace file (MCAP or binary ``.osi``).

    :param path: ``*.mcap`` (one file, a channel per type) or ``*.osi`` (a file per
        type: with one type the file itself, with more ``<stem>_sv.osi`` ...).
    :param message_types: the types written (``"SensorView"``, ``"SensorData"``).
    :param description: the trace's description (MCAP metadata).
    :raises InputError: another suffix or message type.
    """

    def __init__(
        self,
        path: str | Path,
        message_types: Sequence[str] = ("SensorView", "SensorData"),
        description: str = "aldm-gym",
    ) -> None:
        self.path = Path(path)
        suffix = _check_suffix(self.path)
        bad = [m for m in message_types if m not in SHORT_CODE or m == "GroundTruth"]
        if bad or not message_types:
            raise InputError(
                "message_types must be some of ['SensorView', 'SensorData'], "
                f"got {list(message_types)}"
            )
        self.message_types = tuple(message_types)
        ou = _utilities()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        version = ".".join(str(v) for v in interface_version())
        import google.protobuf

        protobuf_version = google.protobuf.__version__
        self.files: dict[str, Path] = {}
        self._single: dict[str, Any] = {}
        self._multi: Any = None
        self.count = 0
        if suffix == ".mcap":
            from osi_utilities.tracefile.writers import prepare_required_file_metadata

            meta = prepare_required_file_metadata()
            meta.update(
                version=version,  # the OSI release the trace conforms to
                min_osi_version=version,
                max_osi_version=version,
                description=description,
                data_sources="aldm-gym",
            )
            self._multi = ou.MultiTraceWriter()
            if not self._multi.open(self.path, meta):
                raise TraceError(f"{self.path}: cannot open for writing")
            for kind in self.message_types:
                self._multi.add_channel(
                    kind,
                    getattr(osi3, kind),
                    {
                        "net.asam.osi.trace.channel.osi_version": version,
                        "net.asam.osi.trace.channel.protobuf_version": protobuf_version,
                        "net.asam.osi.trace.channel.description": f"{kind} from {description}",
                    },
                )
                self.files[kind] = self.path
        else:
            for kind in self.message_types:
                target = self.path if len(self.message_types) == 1 else binary_path(self.path, kind)
                writer = ou.SingleTraceWriter()
                if not writer.open(target):
                    raise TraceError(f"{target}: cannot open for writing")
                self._single[kind] = writer
                self.files[kind] = target

    def write(self, message: Any) -> None:
        """Write one message to its type's channel (or file).

        :raises InputError: a message type this trace was not opened for.
        :raises TraceError: the write failed (disk full, closed).
        """
        kind = message.DESCRIPTOR.name
        if kind not in self.message_types:
            raise InputError(
                f"{self.path}: this trace holds {list(self.message_types)}, not {kind}"
            )
        ok = (
            self._multi.write_message(message, kind)
            if self._multi is not None
            else self._single[kind].write_message(message)
        )
        if not ok:
            raise TraceError(f"{self.files[kind]}: writing message {self.count} failed")
        self.count += 1

    def close(self) -> None:
        """Finish the file(s) (MCAP writes its summary here)."""
        if self._multi is not None:
            self._multi.close()
            self._multi = None
        for writer in self._single.values():
            writer.close()
        self._single = {}

    def __enter__(self) -> TraceWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _binary_type(path: Path, message_type: str | None) -> str:
    if message_type is not None:
        return message_type
    ou = _utilities()
    inferred = ou.infer_message_type_from_filename(path.name)
    if inferred.value in INPUT_TYPES or inferred.value == "SensorData":
        return str(inferred.value)
    return "SensorView"


def read_messages(
    path: str | Path, message_type: str | None = None, topic: str | None = None
) -> Iterator[tuple[int, Any]]:
    """``(frame index, message)`` of every ``SensorView`` or ``GroundTruth`` in a trace.

    :param path: an ``.mcap`` or ``.osi`` file.
    :param message_type: ``"SensorView"`` or ``"GroundTruth"``; default: an MCAP's
        SensorView channel (else its GroundTruth one), a ``.osi`` file's type from its
        name (``*_gt.osi``, ``*_gt_*.osi``), else SensorView.
    :param topic: the MCAP channel to read (default: by ``message_type``).
    :raises TraceError: naming the file (and the frame): a missing, truncated or
        unreadable file, no channel of an input type, a message that cannot be
        parsed.
    """
    path = Path(path)
    suffix = _check_suffix(path)
    if message_type is not None and message_type not in INPUT_TYPES:
        raise InputError(f"message_type must be one of {list(INPUT_TYPES)}, got {message_type!r}")
    if not path.is_file():
        raise TraceError(f"{path}: no such trace file")
    ou = _utilities()
    # the library logs each problem before returning it; the errors raised here say it
    logging.getLogger("osi_utilities").setLevel(logging.CRITICAL)
    if suffix == ".osi":
        kind = _binary_type(path, message_type)
        if kind not in INPUT_TYPES:
            raise TraceError(
                f"{path}: the name says it holds {kind} messages; frames are read from "
                f"{list(INPUT_TYPES)} (pass the message type if the name is wrong)"
            )
        reader = ou.SingleTraceReader()
        reader.set_message_type(ou.MessageType(kind))
        if not reader.open(path):
            raise TraceError(f"{path}: cannot open the trace")
    else:
        reader = ou.MultiTraceReader()
        if not reader.open(path):
            raise TraceError(f"{path}: not a readable MCAP file (truncated or another format?)")
        specs = reader.list_channel_specifications()
        if not specs and reader._summary is None:
            reader.close()
            raise TraceError(f"{path}: the MCAP file has no summary (truncated?)")
        channels = {s.topic: s.message_type.value for s in specs}
        if topic is not None:
            if topic not in channels:
                reader.close()
                raise TraceError(f"{path}: no channel {topic!r}; channels: {channels}")
            chosen = topic
        else:
            wanted = [message_type] if message_type else list(INPUT_TYPES)
            chosen = next(
                (t for w in wanted for t, k in channels.items() if k == w),
                None,
            )
            if chosen is None:
                reader.close()
                raise TraceError(
                    f"{path}: no {' or '.join(wanted)} channel to read frames from; "
                    f"channels: {channels}"
                )
        if channels[chosen] not in INPUT_TYPES:
            reader.close()
            raise TraceError(
                f"{path}: channel {chosen!r} holds {channels[chosen]}, not ground truth"
            )
        reader.set_topics([chosen])
    index = 0
    try:
        while True:
            try:
                result = reader.read_message()
            except Exception as exc:  # the mcap library raises its own kinds
                raise TraceError(f"{path} frame {index}: cannot read ({exc})") from exc
            if result is None:
                return
            if result.status.value != "ok" or result.message is None:
                raise TraceError(f"{path} frame {index}: {result.error_message or result.status}")
            yield index, result.message
            index += 1
    finally:
        reader.close()
