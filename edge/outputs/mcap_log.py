"""Log readings (and optionally frames and contact masks) to an MCAP file (the ``mcap`` extra).

The file uses the ROS 2 profile: ``ros2msg`` schemas and CDR messages, the same types and
topics as the live ROS 2 output, so ``ros2 bag info/play`` and Foxglove open it:

- ``/tactile/force`` (``topic``): geometry_msgs/msg/WrenchStamped, force.z in N (NaN: no estimate)
- ``/tactile/force/diagnostics``: diagnostic_msgs/msg/DiagnosticArray (flags, interval, latency in ms)
- ``/tactile/force/interval``: geometry_msgs/msg/Vector3Stamped, the interval in N (x low, y estimate, z high)
- ``/tactile/<sensor>/image/compressed``: sensor_msgs/msg/CompressedImage, JPEG of the
  HxWx3 uint8 BGR frame (``frames=True``)
- ``/tactile/<sensor>/contact_mask/compressed``: sensor_msgs/msg/CompressedImage, PNG of
  the HxW contact mask, 255 = contact (``mask=True``)

Crash-safe: every ``flush_every`` readings (default every reading, like the CSV/JSONL
writers) the chunk in progress is written out *followed by a provisional end* (a DataEnd
record, a Footer without summary and the closing magic), so the file on disk is a complete
MCAP after every reading. The next write lands after that end, and only then is the old end
turned into a padding record (an unknown opcode, which MCAP readers skip) by one small
write that never crosses a 4 KiB page. So after ``kill -9`` (or a crash) at any moment the
``mcap`` library's own readers (``make_reader(f).iter_messages()``, seeking or not) read
every reading whose flush had returned; :func:`read_messages` ``recover=True`` reads them
too. ``close()`` writes the summary (chunk indexes, statistics) and the real footer; the
``tactile-force run`` CLI closes it on SIGTERM and SIGINT as well. A power cut keeps what
the operating system had written: pass ``fsync=True`` to force each flush to the disk.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np

from ..errors import FrameError, SceneError, require
from ..reading import ForceReading
from .ros2_names import StampClock, ros_topic

#: JPEG quality of logged frames (0..100).
JPEG_QUALITY = 90


class McapMessage(NamedTuple):
    """One message read back: topic, ROS 2 type name, log time (ns since the epoch), CDR bytes."""

    topic: str
    type_name: str
    log_time_ns: int
    data: bytes


def image_topic(namespace: str, sensor: str, what: str = "image") -> str:
    """``<namespace>/<sensor>/<what>/compressed``; SceneError when ``sensor`` is not a valid
    ROS 2 name token."""
    return ros_topic(f"{namespace}/{sensor}/{what}/compressed", f"image topic for sensor {sensor!r}")


def image_payloads(namespace: str, sensor: str, timestamp_ns: int, frame_bgr: np.ndarray | None,
                   mask: np.ndarray | None, clock: StampClock) -> list[tuple[str, str, bytes]]:
    """(topic, type name, CDR bytes) of a frame (HxWx3 uint8 BGR -> JPEG CompressedImage)
    and a contact mask (HxW bool/uint8, non-zero = contact -> PNG, 255 = contact), each
    when not None. FrameError (a ValueError) naming the sensor for a wrong shape or dtype."""
    from . import ros2_messages as m

    out = []
    if frame_bgr is not None:
        if frame_bgr.ndim != 3 or frame_bgr.shape[2] != 3 or frame_bgr.dtype != np.uint8:
            raise FrameError(f"frame of {sensor}: shape {frame_bgr.shape} {frame_bgr.dtype}; expected HxWx3 uint8 BGR")
        ok, buf = cv2.imencode(".jpg", frame_bgr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        if not ok:
            raise FrameError(f"frame of {sensor}: OpenCV could not encode it as JPEG")
        out.append((image_topic(namespace, sensor), m.COMPRESSED_IMAGE,
                    m.compressed_image(sensor, timestamp_ns, buf.tobytes(), "jpeg", clock).serialize()))
    if mask is not None:
        if mask.ndim != 2 or mask.dtype not in (np.bool_, np.uint8):
            raise FrameError(f"contact mask of {sensor}: shape {mask.shape} {mask.dtype}; expected HxW bool or uint8")
        ok, buf = cv2.imencode(".png", np.where(mask != 0, 255, 0).astype(np.uint8))
        if not ok:
            raise FrameError(f"contact mask of {sensor}: OpenCV could not encode it as PNG")
        out.append((image_topic(namespace, sensor, "contact_mask"), m.COMPRESSED_IMAGE,
                    m.compressed_image(sensor, timestamp_ns, buf.tobytes(), "png", clock).serialize()))
    return out


#: Opcode of the padding records that retire a provisional end (0x80-0xFF: private records,
#: which MCAP readers skip).
_PAD_OPCODE = 0x80
_PAGE = 4096


def _pad_record(size: int) -> bytes:
    """An unknown-opcode record of exactly ``size`` bytes (>= 9): opcode, length, zeros."""
    return struct.pack("<BQ", _PAD_OPCODE, size - 9) + bytes(size - 9)


def _provisional_end() -> bytes:
    """DataEnd + Footer without summary + magic: what makes a data section a complete MCAP."""
    from mcap.data_stream import RecordBuilder
    from mcap.records import DataEnd, Footer
    from mcap.writer import MCAP0_MAGIC

    b = RecordBuilder()
    DataEnd(data_section_crc=0).write(b)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(b)
    return b.end() + MCAP0_MAGIC


def _pwrite_all(fd: int, data: bytes, offset: int) -> None:
    view = memoryview(data)
    while view:
        if hasattr(os, "pwrite"):
            n = os.pwrite(fd, view, offset)
        else:  # pragma: no cover - Windows
            os.lseek(fd, offset, os.SEEK_SET)
            n = os.write(fd, view)
        view = view[n:]
        offset += n


class _CommittingFile:
    """The stream the mcap Writer writes to: bytes are held until :meth:`commit`, which puts
    them on disk followed by a provisional end, then retires the previous end (see the
    module docstring). ``tell()`` is the file offset the next byte will have."""

    def __init__(self, path: Path, fsync: bool) -> None:
        self._fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_TRUNC | getattr(os, "O_BINARY", 0), 0o666)
        self._fsync = fsync
        self._pending = bytearray()
        self._pos = 0  # where pending[0] goes
        self._old_end: int | None = None  # offset of the provisional end on disk
        self._end = _provisional_end()

    def write(self, data: bytes) -> int:
        self._pending += data
        return len(data)

    def tell(self) -> int:
        return self._pos + len(self._pending)

    def flush(self) -> None:
        self.commit()

    def commit(self, final: bool = False) -> None:
        """Write the held bytes (and, unless ``final``, a provisional end after them), then
        retire the previous provisional end; ``final``: the Writer wrote the real end."""
        data = bytes(self._pending)
        if not data and not final:
            return
        end_at = self._pos + len(data)
        if not final:
            end = self._end
            into_page = end_at % _PAGE
            if into_page + len(end) > _PAGE:  # keep the end inside one page: retiring it is one small write
                pad = _PAGE - into_page
                pad += _PAGE if pad < 9 else 0
                data += _pad_record(pad)
                end_at += pad
            data += end
        _pwrite_all(self._fd, data, self._pos)
        self._sync()
        if self._old_end is not None:
            _pwrite_all(self._fd, _pad_record(len(self._end)), self._old_end)
            self._sync()
        self._pending.clear()
        if final:
            self._old_end = None
            os.ftruncate(self._fd, end_at)
            self._pos = end_at
        else:
            self._old_end = end_at
            self._pos = end_at + len(self._end)

    def _sync(self) -> None:
        if self._fsync:
            os.fsync(self._fd)

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class McapWriter:
    """A reading sink that writes one MCAP file in the ROS 2 profile.

    Parameters
    ----------
    path : str or PathLike
        Output file (parent folders are made).
    frames : bool
        Accept frames through :meth:`write_frame` (JPEG CompressedImage per sensor).
    mask : bool
        Accept contact masks through :meth:`write_frame` (PNG CompressedImage per sensor).
    topic : str
        ROS 2 topic of the readings; diagnostics go on ``topic + '/diagnostics'``, images
        under the topic's parent namespace.
    flush_every : int
        Close the chunk and flush the file every this many readings (>= 1).
    fsync : bool
        Also force each flush to the disk (slower).
    stamp_clock : StampClock, optional
        Monotonic frame time -> ROS time; default the wall - monotonic offset at start.
    """

    def __init__(self, path: str | os.PathLike, *, frames: bool = False, mask: bool = False,
                 topic: str = "/tactile/force", flush_every: int = 1, fsync: bool = False,
                 stamp_clock: StampClock | None = None) -> None:
        if isinstance(flush_every, bool) or not isinstance(flush_every, int) or flush_every < 1:
            raise SceneError(f"MCAP flush_every={flush_every!r}: expected an integer >= 1")
        self.topic = ros_topic(topic, "MCAP topic")
        self.namespace = self.topic.rsplit("/", 1)[0]
        self.frames = frames
        self.mask = mask
        self.flush_every = flush_every
        self.fsync = fsync
        self.clock = stamp_clock or StampClock()
        self.path = Path(path)
        require("mcap", "mcap", "MCAP output")
        require("cyclonedds", "mcap", "MCAP output (CDR serialisation)")
        from mcap.writer import CompressionType, Writer

        from . import ros2_messages as msgs

        self._msgs = msgs
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh = _CommittingFile(self.path, fsync)  # held open until close()
        # Chunks hold a reading or a few; compressing them gains little, and JPEG/PNG are compressed.
        self._writer = Writer(self._fh, compression=CompressionType.NONE)  # type: ignore[arg-type]
        self._writer.start(profile="ros2", library="tactile-force")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._since_flush = 0
        self.readings = 0
        self._closed = False
        self._channel(self.topic, msgs.WRENCH_STAMPED)
        self._channel(self.topic + "/diagnostics", msgs.DIAGNOSTIC_ARRAY)
        self._flush()

    # -- channels ---------------------------------------------------------------------------------
    def _channel(self, topic: str, type_name: str) -> int:
        if topic in self._channels:
            return self._channels[topic]
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding="ros2msg", data=self._msgs.MSG_DEFINITIONS[type_name].encode())
        cid = self._writer.register_channel(topic=topic, message_encoding="cdr", schema_id=self._schemas[type_name])
        self._channels[topic] = cid
        return cid

    def image_topic(self, sensor: str, what: str = "image") -> str:
        """``<namespace>/<sensor>/<what>/compressed``; SceneError for a sensor name that is
        not a valid ROS 2 name token."""
        return image_topic(self.namespace, sensor, what)

    def _add(self, topic: str, type_name: str, monotonic_ns: int, data: bytes) -> None:
        cid = self._channel(topic, type_name)
        t = self.clock.ros_ns(monotonic_ns)
        seq = self._sequence.get(cid, 0)
        self._sequence[cid] = seq + 1
        self._writer.add_message(channel_id=cid, log_time=t, publish_time=t, data=data, sequence=seq)

    def _flush(self) -> None:
        self._writer.flush()  # closes the chunk in progress; the stream's flush commits it with a provisional end
        self._since_flush = 0

    # -- sink protocol ----------------------------------------------------------------------------
    def write(self, reading: ForceReading) -> None:
        """Log one reading (WrenchStamped + DiagnosticArray)."""
        if self._closed:
            raise RuntimeError(f"MCAP file {self.path}: write after close")
        for topic, type_name, data in self._msgs.reading_payloads(reading, self.clock, self.topic):
            self._add(topic, type_name, reading.timestamp_ns, data)
        self.readings += 1
        self._since_flush += 1
        if self._since_flush >= self.flush_every:
            self._flush()

    def write_frame(self, sensor: str, timestamp_ns: int, frame_bgr: np.ndarray | None,
                    mask: np.ndarray | None = None) -> None:
        """Log the frame (HxWx3 uint8 BGR, JPEG) and/or contact mask (HxW bool or uint8,
        non-zero = contact, PNG) of a reading; each only when enabled at construction.
        Flushed with the next reading. FrameError (a ValueError) for a wrong shape or dtype."""
        if self._closed:
            raise RuntimeError(f"MCAP file {self.path}: write after close")
        for topic, type_name, data in image_payloads(self.namespace, sensor, timestamp_ns,
                                                     frame_bgr if self.frames else None,
                                                     mask if self.mask else None, self.clock):
            self._add(topic, type_name, timestamp_ns, data)

    def close(self) -> None:
        """Write the last chunk, the summary and the footer, and close the file; safe twice."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()
            self._fh.commit(final=True)
        finally:
            self._fh.close()

    def __enter__(self) -> McapWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_messages(path: str | os.PathLike, recover: bool = False) -> Iterator[McapMessage]:
    """The messages of an MCAP file in file order.

    recover=False: the file must be complete (summary and footer); McapError otherwise.
    recover=True: read record by record and stop quietly at the first truncated or damaged
    record, as left by a killed run: every complete chunk before it is returned.
    """
    require("mcap", "mcap", "reading MCAP files")
    from mcap.exceptions import InvalidMagic, McapError
    from mcap.reader import make_reader
    from mcap.records import Channel, Chunk, Message, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    with open(path, "rb") as fh:
        if not recover:
            for schema, channel, message in make_reader(fh).iter_messages(log_time_order=False):
                yield McapMessage(channel.topic, schema.name if schema else "", message.log_time, message.data)
            return
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, int]] = {}
        records = StreamReader(fh, emit_chunks=True).records
        while True:
            try:
                record = next(records)
                inner = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else [record]
            except StopIteration:
                return
            except InvalidMagic:
                raise
            except (McapError, EOFError, ValueError, IndexError, struct.error):  # truncated tail of a killed run
                return
            for rec in inner:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec.name
                elif isinstance(rec, Channel):
                    channels[rec.id] = (rec.topic, rec.schema_id)
                elif isinstance(rec, Message):
                    topic, schema_id = channels[rec.channel_id]
                    yield McapMessage(topic, schemas.get(schema_id, ""), rec.log_time, rec.data)
