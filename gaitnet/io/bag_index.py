"""A ROS1 ``.bag`` file: its index, positioned reads of single messages, and their decoding.

:class:`RosBag` is the only public entry point. Opening reads the bag's index with ``rosbags``
(topics, connections and, per connection, where each message lies: a :class:`MessageRef`) and
the header of every chunk; nothing else. :meth:`RosBag.read` then reads just one message's
payload with ``os.pread`` (uncompressed chunks: small positioned reads; compressed chunks are
decompressed once each and cached), :meth:`RosBag.decode` deserializes it with ``rosbags``;
every message type is registered from the bag's own message definitions
(``connection.msgdef``), so vendor types such as the RealSense SDK's ``realsense_msgs/*``
work. :func:`parse_imu_payload` is a fast path for standard ``sensor_msgs/Imu`` payloads.

Errors: a file that is not a ROS1 bag, a bag without an index (a recording that was cut off:
the message says how to rebuild it), a damaged index or damaged records raise
:class:`~gaitnet.errors.SessionError` with a one-line message that names the bag file. A chunk
is damaged when it does not decompress (its codec's own checks: bz2's CRC, an LZ4 frame's
checksums where the frame has them) or when it holds, or decompresses to, another number of
bytes than its header's ``size``; the message names the chunk by its byte offset in the file.
ROS1 bags carry no checksum of their own, so changed bytes inside a chunk's messages that
leave its size intact are not noticed here (the readers' value checks may still catch them).
"""

from __future__ import annotations

import bz2
import logging
import os
import struct
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gaitnet.errors import SessionError

log = logging.getLogger(__name__)

_U32 = struct.Struct("<I")
_OP_MSGDATA = 2
_OP_CHUNK = 5
_OP_CONNECTION = 7


class _DamagedError(Exception):
    """A record of the bag is damaged (turned into SessionError at the public boundary)."""


def _parse_header(buf: bytes) -> dict[bytes, bytes]:
    fields: dict[bytes, bytes] = {}
    pos, n = 0, len(buf)
    while pos < n:
        if pos + 4 > n:
            raise _DamagedError("record header field size is cut off")
        (size,) = _U32.unpack_from(buf, pos)
        pos += 4
        if pos + size > n:
            raise _DamagedError("record header field runs past the header")
        name, sep, value = buf[pos : pos + size].partition(b"=")
        if not sep:
            raise _DamagedError("record header field without '='")
        fields[name] = value
        pos += size
    return fields


@dataclass(frozen=True)
class _ChunkLoc:
    datapos: int
    datasize: int
    compression: str
    size: int = -1  # the header's uncompressed size (-1: not checked)


@dataclass(frozen=True, slots=True)
class MessageRef:
    """Where one message lies: record time [ns], chunk position, offset in the chunk, connection.

    ``time`` is the bag's record time (when the message was written), not its header stamp.
    """

    time: int
    chunk_pos: int
    offset: int
    conn: int


class _Records:
    """Positioned reads of single messages (``os.pread``: safe across threads and forks)."""

    def __init__(self, path: Path, src: str) -> None:
        self.path = path
        self.src = src
        self.chunks: dict[int, _ChunkLoc] = {}
        self._fh = None
        self._pid = -1
        self._lock = threading.Lock()
        self._cache: OrderedDict[int, bytes] = OrderedDict()

    def __getstate__(self) -> dict:
        return {"path": self.path, "src": self.src, "chunks": self.chunks}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["path"], state["src"])
        self.chunks = state["chunks"]

    def close(self) -> None:
        with self._lock:
            if self._fh is not None:
                self._fh.close()
            self._fh = None
            self._cache.clear()

    def _fd(self) -> int:
        if self._fh is None or self._pid != os.getpid():
            try:
                self._fh = open(self.path, "rb")  # noqa: SIM115 - kept open, closed by close()
            except OSError as exc:
                raise SessionError(f"{self.src}: cannot open the bag ({exc.strerror})") from exc
            self._pid = os.getpid()
        return self._fh.fileno()

    def read_file(self, pos: int, n: int) -> bytes:
        data = os.pread(self._fd(), n, pos)
        if len(data) != n:
            raise _DamagedError(f"file ends at byte {pos + len(data)}, expected {n} bytes at {pos}")
        return data

    def scan_chunk(self, pos: int) -> _ChunkLoc:
        """Read the CHUNK record header at file position ``pos``; an uncompressed chunk must
        hold as many bytes as its header's ``size`` says (compressed ones are checked when
        they are decompressed: :meth:`_chunk_data`)."""
        (hl,) = _U32.unpack(self.read_file(pos, 4))
        header = _parse_header(self.read_file(pos + 4, hl))
        if header.get(b"op") != bytes([_OP_CHUNK]):
            raise _DamagedError(f"no chunk record at byte {pos}")
        (datasize,) = _U32.unpack(self.read_file(pos + 4 + hl, 4))
        compression = header.get(b"compression", b"none").decode(errors="replace")
        size_field = header.get(b"size", b"")
        if len(size_field) != 4:
            raise _DamagedError(f"chunk at byte {pos} has no 4-byte size in its header")
        (size,) = _U32.unpack(size_field)
        if compression == "none" and size != datasize:
            raise _DamagedError(
                f"chunk at byte {pos} holds {datasize} bytes, its header says {size}"
            )
        return _ChunkLoc(pos + 8 + hl, datasize, compression, size)

    def _chunk_data(self, chunk_pos: int) -> bytes:
        with self._lock:
            if chunk_pos in self._cache:
                self._cache.move_to_end(chunk_pos)
                return self._cache[chunk_pos]
        loc = self.chunks[chunk_pos]
        raw = self.read_file(loc.datapos, loc.datasize)
        try:
            if loc.compression == "lz4":
                from lz4.frame import decompress as lz4_decompress

                data = lz4_decompress(raw)
            elif loc.compression == "bz2":
                data = bz2.decompress(raw)
            else:
                raise SessionError(f"{self.src}: unsupported chunk compression {loc.compression!r}")
        except SessionError:
            raise
        except Exception as exc:
            raise _DamagedError(f"chunk at byte {chunk_pos} does not decompress ({exc})") from exc
        if loc.size >= 0 and len(data) != loc.size:
            raise _DamagedError(
                f"chunk at byte {chunk_pos} decompresses to {len(data)} bytes, its header says "
                f"{loc.size}"
            )
        with self._lock:
            self._cache[chunk_pos] = data
            while len(self._cache) > 4:
                self._cache.popitem(last=False)
        return data

    def message(self, entry: MessageRef, limit: int | None = None) -> tuple[bytes, int]:
        """Serialized message at ``entry`` (its first ``limit`` bytes) and its full length."""
        try:
            return self._message(entry, limit)
        except _DamagedError as exc:
            raise SessionError(f"{self.src}: bag data looks damaged ({exc})") from None
        except struct.error as exc:
            raise SessionError(f"{self.src}: bag data looks damaged ({exc})") from None

    def _message(self, entry: MessageRef, limit: int | None) -> tuple[bytes, int]:
        loc = self.chunks.get(entry.chunk_pos)
        if loc is None:
            raise _DamagedError(f"index points to unknown chunk at byte {entry.chunk_pos}")
        if loc.compression == "none":
            # One read of a small window usually holds the record header and, for small
            # messages (IMU), the whole payload; anything beyond it is read separately.
            w0 = entry.offset
            window = self.read_file(loc.datapos + w0, max(0, min(4096, loc.datasize - w0)))

            def read(p: int, n: int) -> bytes:
                if p < 0 or p + n > loc.datasize:
                    raise _DamagedError(f"record runs past its chunk at byte {entry.chunk_pos}")
                if w0 <= p and p + n <= w0 + len(window):
                    return window[p - w0 : p - w0 + n]
                return self.read_file(loc.datapos + p, n)

        else:
            buf = self._chunk_data(entry.chunk_pos)

            def read(p: int, n: int) -> bytes:
                if p < 0 or p + n > len(buf):
                    raise _DamagedError(f"record runs past its chunk at byte {entry.chunk_pos}")
                return buf[p : p + n]

        pos = entry.offset
        while True:
            (hl,) = _U32.unpack(read(pos, 4))
            header = _parse_header(read(pos + 4, hl))
            (dl,) = _U32.unpack(read(pos + 4 + hl, 4))
            data_pos = pos + 8 + hl
            op = header.get(b"op")
            if op == bytes([_OP_CONNECTION]):
                pos = data_pos + dl
                continue
            if op != bytes([_OP_MSGDATA]):
                raise _DamagedError(f"no message record at offset {pos} of chunk {entry.chunk_pos}")
            return read(data_pos, dl if limit is None else min(dl, limit)), dl


class _Types:
    """Typestores built from the bag's own message definitions, one per connection."""

    def __init__(self, defs: dict[int, tuple[str, str]], src: str) -> None:
        self.defs = defs  # connection id -> (normalized msgtype, msgdef text)
        self.src = src
        self._base = None
        self._stores: dict[tuple[str, str], Any] = {}

    def __getstate__(self) -> dict:
        return {"defs": self.defs, "src": self.src}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["defs"], state["src"])

    def store(self, conn: int) -> Any:
        from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

        key = self.defs[conn]
        if key in self._stores:
            return self._stores[key]
        msgtype, text = key
        if self._base is None:
            self._base = get_typestore(Stores.ROS1_NOETIC)
        store = self._base
        if text.strip():
            try:
                types = get_types_from_msg(text, msgtype)
            except Exception as exc:
                if msgtype not in self._base.types:
                    raise SessionError(
                        f"{self.src}: cannot parse the message definition of {msgtype} ({exc})"
                    ) from None
                types = None
            if types is not None:
                try:
                    self._base.register(types)
                except TypesysError:
                    # The bag defines a type differently from ROS1 Noetic (e.g. a vendor
                    # variant): decode this connection with its own store.
                    store = get_typestore(Stores.EMPTY)
                    store.register(types)
                    log.debug("%s: %s has a non-standard definition", self.src, msgtype)
        elif msgtype not in self._base.types:
            raise SessionError(f"{self.src}: no message definition for type {msgtype}")
        self._stores[key] = store
        return store

    def decode(self, conn: int, raw: bytes, topic: str) -> Any:
        msgtype = self.defs[conn][0]
        try:
            return self.store(conn).deserialize_ros1(raw, msgtype)
        except SessionError:
            raise
        except Exception as exc:
            raise SessionError(
                f"{self.src}: cannot decode a {msgtype} message on {topic} ({exc})"
            ) from None

    def is_standard(self, conn: int, msgtype: str) -> bool:
        """Whether ``conn`` carries ``msgtype`` exactly as ROS1 Noetic defines it."""
        if self.defs[conn][0] != msgtype:
            return False
        store = self.store(conn)
        return store is self._base and msgtype in store.fielddefs

    def header_first(self, conn: int) -> bool:
        """Whether messages of ``conn`` start with a ROS1 ``Header`` (seq, stamp, …)."""
        store = self.store(conn)
        msgtype = self.defs[conn][0]
        fields = store.fielddefs.get(msgtype, ([], []))[1]
        if not fields or fields[0][1][-1] != "std_msgs/msg/Header":
            return False
        hdr = store.fielddefs.get("std_msgs/msg/Header", ([], []))[1]
        return [f[0] for f in hdr[:2]] == ["seq", "stamp"]


_IMU_TAIL_DOUBLES = 4 + 9 + 3 + 9 + 3 + 9  # orientation, cov, gyro, cov, accel, cov
NS_PER_S = 1_000_000_000


def stamp_ns(sec: int, nsec: int) -> int:
    """Nanoseconds of a ROS1 time ``(sec, nsec)``; ``ValueError`` if ``nsec`` is not below 1e9."""
    if not 0 <= int(nsec) < NS_PER_S or int(sec) < 0:
        raise ValueError(f"invalid time stamp (sec {sec}, nsec {nsec})")
    return int(sec) * NS_PER_S + int(nsec)


def parse_imu_payload(raw: bytes, gyro: bool) -> tuple[int, tuple[float, float, float]] | None:
    """Stamp [ns] and gyro (or accel) vector of a standard ROS1 ``sensor_msgs/Imu`` payload.

    A direct ``struct`` read, ~10× faster than generic deserialization (IMU streams have
    hundreds of thousands of messages); None if the size does not fit the standard layout.
    ``ValueError`` for an invalid stamp.
    """
    if len(raw) < 16:
        return None
    _, sec, nsec, frame_id_len = struct.unpack_from("<IIII", raw, 0)
    base = 16 + frame_id_len
    if len(raw) != base + 8 * _IMU_TAIL_DOUBLES:
        return None
    vec = struct.unpack_from("<3d", raw, base + 8 * (13 if gyro else 25))
    return stamp_ns(sec, nsec), vec


def _index_hint(path: Path) -> str:
    return (
        f"rebuild the index with `rosbag reindex {path.name}` (ROS1 tools; the original is "
        "kept as .orig.bag), or open the recording in RealSense Viewer and save it again"
    )


class RosBag:
    """An open ROS1 bag: topics, message references, positioned reads and decoding.

    Args:
        path: the ``.bag`` file.
        src: how errors name the file (default: ``str(path)``).

    Raises:
        SessionError: not a ROS1 bag, no index (recording cut off), damaged index or chunks,
            no messages at all.

    The object pickles (file handles are reopened in the new process), so readers built on
    it can be sent to worker processes.
    """

    def __init__(self, path: str | Path, src: str | None = None) -> None:
        from rosbags.rosbag1 import Reader

        self.path = Path(path)
        self.src = src or str(self.path)
        try:
            reader = Reader(self.path)
            reader.open()
        except PermissionError as exc:
            raise SessionError(f"{self.src}: cannot open the bag ({exc.strerror})") from None
        except Exception as exc:
            why = " ".join(str(exc).split()) or type(exc).__name__
            if "not indexed" in why:
                raise SessionError(
                    f"{self.src}: the bag has no index (was the recording cut off?); "
                    + _index_hint(self.path)
                ) from None
            if "index" in why.lower() or isinstance(exc, (EOFError, struct.error)):
                raise SessionError(
                    f"{self.src}: the bag's index is damaged or the file is truncated ({why}); "
                    + _index_hint(self.path)
                ) from None
            raise SessionError(f"{self.src}: not a readable ROS1 bag ({why})") from None
        try:
            self.topics: dict[str, list[int]] = {}
            defs: dict[int, tuple[str, str]] = {}
            for conn in reader.connections:
                self.topics.setdefault(conn.topic, []).append(conn.id)
                defs[conn.id] = (conn.msgtype, conn.msgdef.data)
            # rosbags' per-connection index lists (time, chunk_pos, offset), kept as they are;
            # MessageRef objects are made only for the topics that are read.
            self._index = {cid: list(idx) for cid, idx in reader.indexes.items()}
            chunk_positions = [info.pos for info in reader.chunk_infos]
        finally:
            reader.close()
        if not any(self._index.values()):
            raise SessionError(f"{self.src}: the bag contains no messages")
        self._records = _Records(self.path, self.src)
        try:
            self._records.chunks = {p: self._records.scan_chunk(p) for p in chunk_positions}
        except (_DamagedError, struct.error) as exc:
            raise SessionError(f"{self.src}: bag data looks damaged ({exc})") from None
        self._types = _Types(defs, self.src)

    def count(self, topic: str) -> int:
        """Number of messages on ``topic`` (0 if absent)."""
        return sum(len(self._index.get(cid, ())) for cid in self.topics.get(topic, ()))

    def refs(self, topic: str) -> list[MessageRef]:
        """Where the messages on ``topic`` lie, in record-time order (ties: file order)."""
        out: list[MessageRef] = []
        for cid in self.topics.get(topic, []):
            out.extend(MessageRef(e[0], e[1], e[2], cid) for e in self._index.get(cid, ()))
        out.sort(key=lambda e: (e.time, e.chunk_pos, e.offset))
        return out

    def keep_only(self, topics: set[str]) -> None:
        """Forget the index of every other topic (memory: long recordings have millions)."""
        keep = {cid for t in topics for cid in self.topics.get(t, ())}
        self._index = {cid: idx for cid, idx in self._index.items() if cid in keep}

    def read(self, ref: MessageRef, limit: int | None = None) -> bytes:
        """The serialized message at ``ref`` (only its first ``limit`` bytes when given)."""
        return self._records.message(ref, limit)[0]

    def read_head(self, ref: MessageRef, limit: int) -> tuple[bytes, int]:
        """The first ``limit`` bytes of the message at ``ref`` and its full length in bytes."""
        return self._records.message(ref, limit)

    def decode(self, ref: MessageRef, topic: str, raw: bytes | None = None) -> Any:
        """Deserialize the message at ``ref`` (or its already read bytes ``raw``)."""
        if raw is None:
            raw = self.read(ref)
        return self._types.decode(ref.conn, raw, topic)

    def decode_all(self, topic: str) -> list[Any]:
        """Every message on a (small, static) topic, decoded, in record-time order."""
        return [self.decode(ref, topic) for ref in self.refs(topic)]

    def msgtype(self, conn: int) -> str:
        """The (normalized) message type of a connection, e.g. ``sensor_msgs/msg/Image``."""
        return self._types.defs[conn][0]

    def is_standard(self, conn: int, msgtype: str) -> bool:
        """Whether ``conn`` carries ``msgtype`` exactly as ROS1 Noetic defines it."""
        return self._types.is_standard(conn, msgtype)

    def header_first(self, conn: int) -> bool:
        """Whether messages of ``conn`` start with a ROS1 ``Header`` (seq, stamp, …)."""
        return self._types.header_first(conn)

    def close(self) -> None:
        """Close the file handle (reopened automatically by the next read)."""
        self._records.close()
