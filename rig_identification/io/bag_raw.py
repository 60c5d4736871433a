"""Raw message bytes of chosen topics of a rosbag2, in bulk, in the order rosbags yields them.

:func:`read_topics` hands the serialized messages of each topic to a ``decode`` callback in
batches — a byte buffer with message offsets and sizes, never one Python object per
message kept — and returns each topic's decoded rows in exactly the order
``AnyReader.messages`` yields that topic's messages (its order decides which of two
samples with one stamp survives, and whether a topic is out of stamp order).

Three sources, in order of preference:

* MCAP files with a chunk index (what ``ros2 bag record`` and rosbags write): every chunk is
  read whole, decompressed with rosbags' own ``decompress`` (same checks), and its messages
  located through the chunk's message index records (MCAP spec: Message Index, op 0x07:
  per channel, (log_time, offset) pairs of 16 bytes).  The index is verified against the
  records (op code, channel, bounds; every byte of the chunk accounted for by indexed
  messages or non-message records).  The order is rosbags' ``McapReader.messages``: files in
  turn, then (log_time, chunk offset, position in the chunk).
* sqlite3 files: rosbags' own query (``Sqlite3Reader.messages``) on its connection, rows
  taken in blocks.
* anything else (per-message compression, unindexed MCAP, an index that does not match its
  chunk): ``AnyReader.messages``, taken in blocks.

The storage classes are rosbags' (``rosbags.rosbag2``); their attributes read here
(``storages``, ``chunks``, ``channel_count``, ``dbconn``) are checked for before use, and a
bag without them is read through ``AnyReader.messages``.
"""
from __future__ import annotations

import struct
from collections.abc import Callable, Iterator, Sequence
from itertools import islice
from operator import attrgetter
from typing import Any, BinaryIO, NamedTuple

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Connection
from rosbags.rosbag2 import Reader, ReaderError
from rosbags.rosbag2.reader import DirectoryReader
from rosbags.rosbag2.storage_mcap import ChunkInfo, McapReader, decompress
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

from .bag_decode import BytesLike, read_structs

#: decode(topic, buf, offsets, sizes) -> rows: buf (B,) uint8 array or bytes holds n serialized
#: messages (CDR with encapsulation header), message i at ``buf[offsets[i]:offsets[i] + sizes[i]]``;
#: returns an (n, c) float array, one row per message in the given order.
Decode = Callable[[str, BytesLike, np.ndarray, np.ndarray], np.ndarray]

BATCH = 16384            # messages per block on the row paths (bounds the raw buffer and the row tuples)
BATCH_BYTES = 1 << 22    # decompressed MCAP chunk bytes decoded together (bounds the raw buffer: 4 MiB)

MESSAGE_OP, MESSAGE_INDEX_OP = 0x05, 0x07   # MCAP record op codes: Message, Message Index
RECORD_HEAD = 9          # op (1) + record length (8)
MESSAGE_HEAD = 22        # channel id u16, sequence u32, log_time u64, publish_time u64
_U64 = struct.Struct("<Q")
#: The start of an MCAP Message record (op 0x05), packed little-endian.
MESSAGE_RECORD = np.dtype({"names": ["op", "length", "channel", "log_time"],
                           "formats": ["u1", "<u8", "<u2", "<u8"],
                           "offsets": [0, 1, 9, 15], "itemsize": RECORD_HEAD + MESSAGE_HEAD})
_INDEX_HEAD = struct.Struct("<BQHI")   # op, record length, channel id, entries length


class StorageFile(NamedTuple):
    """One storage file of a bag and the topic of each of its connections rosbags would read."""

    storage: McapReader | Sqlite3Reader
    topics: dict[int, str]     # connection (channel/topic table) id -> topic, the wanted ones


class IndexMismatch(Exception):
    """A chunk whose message index does not describe its records: read by iterating instead."""


def storage_files(reader: AnyReader, connections: Sequence[Connection]) -> list[StorageFile] | None:
    """The storage files of ``reader`` with the wanted connections of each, or None when the
    bag is not one rosbag2 (directory, .mcap or .db3) without per-message compression.

    A storage connection is wanted as ``DirectoryReader.messages`` matches it: same topic,
    type, serialization/QoS and (when both have one) type hash as one of ``connections``.
    """
    if len(reader.readers) != 1 or not isinstance(reader.readers[0], Reader):
        return None
    storage = reader.readers[0].storage
    if isinstance(storage, (McapReader, Sqlite3Reader)):
        ids = {c.id for c in connections}
        return [StorageFile(storage, {x.id: x.topic for x in storage.connections if x.id in ids})]
    if not isinstance(storage, DirectoryReader) or storage.metadata.compression_mode == "message":
        return None
    files = []
    for s in storage.storages:
        if not isinstance(s, (McapReader, Sqlite3Reader)):
            return None
        topics = {}
        for x in s.connections:
            if any(y.topic == x.topic and y.msgtype == x.msgtype and y.ext == x.ext
                   and (not x.digest or not y.digest or y.digest == x.digest) for y in connections):
                topics[x.id] = x.topic
        files.append(StorageFile(s, topics))
    return files


def read_chunk(f: BinaryIO, chunk: ChunkInfo) -> tuple[bytes, bytes]:
    """The decompressed records of ``chunk`` and its message index area, as rosbags reads
    them (compression, sizes and offsets from the chunk index; CRC from the chunk record).

    f: the MCAP file, open for binary reading.  Returns (records, index area) bytes.
    Raises ReaderError for a truncated file or a failed decompression/checksum."""
    f.seek(chunk.chunk_start_offset)
    raw = f.read(chunk.chunk_length + chunk.message_index_length)
    head = RECORD_HEAD + 40 + len(chunk.compression)
    if len(raw) != chunk.chunk_length + chunk.message_index_length or head + chunk.compressed_size > len(raw):
        raise ReaderError(f"Truncated chunk at offset {chunk.chunk_start_offset}.")
    (crc,) = struct.unpack_from("<I", raw, RECORD_HEAD + 24)
    data = decompress(raw[head:head + chunk.compressed_size], chunk.compression, chunk.uncompressed_size, crc)
    return data, raw[chunk.chunk_length:]


def _index(chunk: ChunkInfo, area: bytes) -> tuple[np.ndarray, np.ndarray]:
    """(channel ids, record offsets) of every message the chunk's message index lists,
    sorted by offset.  Raises IndexMismatch for a malformed index record."""
    chans, offs = [], []
    base = chunk.chunk_start_offset + chunk.chunk_length
    for cid, pos in chunk.message_index_offsets.items():
        pos -= base
        if pos < 0 or pos + _INDEX_HEAD.size > len(area):
            raise IndexMismatch(f"message index of channel {cid} outside its area")
        op, length, channel, n_bytes = _INDEX_HEAD.unpack_from(area, pos)
        if op != MESSAGE_INDEX_OP or channel != cid or n_bytes % 16 or pos + _INDEX_HEAD.size + n_bytes > len(area):
            raise IndexMismatch(f"malformed message index record of channel {cid}")
        entries = np.frombuffer(area, "<u8", count=n_bytes // 8, offset=pos + _INDEX_HEAD.size)
        offs.append(entries[1::2].astype(np.int64))
        chans.append(np.full(n_bytes // 16, cid, np.int64))
    off = np.concatenate(offs) if offs else np.zeros(0, np.int64)
    order = np.argsort(off, kind="stable")
    return (np.concatenate(chans)[order] if chans else off), off[order]


def _check_gap(data: bytes, start: int, end: int) -> None:
    """The bytes [start, end) of a chunk are whole records none of which is a message.
    Raises IndexMismatch otherwise."""
    p = start
    while p < end:
        if p + RECORD_HEAD > end:
            raise IndexMismatch(f"truncated record at chunk offset {p}")
        if data[p] == MESSAGE_OP:
            raise IndexMismatch(f"message record at chunk offset {p} missing from the message index")
        p += RECORD_HEAD + _U64.unpack_from(data, p + 1)[0]
    if p != end:
        raise IndexMismatch(f"record overruns an indexed message at chunk offset {end}")


class ChunkMessages(NamedTuple):
    """The messages of one chunk, from its index checked against its records."""

    data: np.ndarray        # (B,) uint8: the decompressed chunk
    channel: np.ndarray     # (m,) channel id of each message record, in record order
    offset: np.ndarray      # (m,) record offset in the chunk
    log_time: np.ndarray    # (m,) uint64 ns, from the record (as rosbags reads it)
    size: np.ndarray        # (m,) serialized message size, bytes (data at offset + 31)


def chunk_messages(data: bytes, chunk: ChunkInfo, area: bytes) -> ChunkMessages:
    """Locate every message record of a decompressed chunk through its message index.

    Raises IndexMismatch unless every index entry is a message record of its channel
    inside the chunk, indexed records do not overlap, and the bytes between them are
    non-message records."""
    chan, off = _index(chunk, area)
    buf = np.frombuffer(data, np.uint8)
    size = len(data)
    if len(off) and (off.min() < 0 or off.max() + RECORD_HEAD + MESSAGE_HEAD > size):
        raise IndexMismatch("message index entry outside the chunk")
    head = read_structs(data, off, MESSAGE_RECORD)
    length = head["length"]
    if np.any(head["op"] != MESSAGE_OP) or np.any(head["channel"] != chan):
        raise IndexMismatch("message index entry that is not a message record of its channel")
    if np.any(length < MESSAGE_HEAD) or np.any(length > size):
        raise IndexMismatch("message record of impossible length")
    end = off + RECORD_HEAD + length.astype(np.int64)
    if len(off) and (end[-1] > size or np.any(end[:-1] > off[1:])):
        raise IndexMismatch("overlapping or truncated message records")
    starts = np.concatenate([[0], end])
    stops = np.concatenate([off, [size]])
    for i in np.nonzero(starts != stops)[0]:
        if starts[i] > stops[i]:
            raise IndexMismatch("overlapping records")
        _check_gap(data, int(starts[i]), int(stops[i]))
    return ChunkMessages(buf, chan, off, head["log_time"], length.astype(np.int64) - MESSAGE_HEAD)


def _in_order(keys: list[np.ndarray]) -> bool:
    """Whether rows are already sorted by ``keys`` (most significant first), strictly."""
    later = np.zeros(len(keys[0]) - 1, bool)
    tied = np.ones(len(keys[0]) - 1, bool)
    for k in keys:
        later |= tied & (k[1:] > k[:-1])
        tied &= k[1:] == k[:-1]
    return bool(later.all())


class _Pending(NamedTuple):
    data: np.ndarray        # decompressed chunk
    offset: np.ndarray      # message data offsets in the chunk
    size: np.ndarray
    topic: np.ndarray       # index into the topic list
    log_time: np.ndarray    # uint64 ns
    position: np.ndarray    # uint64: chunk rank in the file (by offset) << 32 | record offset in the chunk


def _read_mcap(files: list[StorageFile], decode: Decode, batch_bytes: int) -> dict[str, np.ndarray]:
    topics = sorted({t for f in files for t in f.topics.values()})
    # per topic, per file: decoded rows and their sort keys (log_time, position)
    parts: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {t: [] for t in topics}
    out: dict[str, list[np.ndarray]] = {t: [] for t in topics}
    pending: list[_Pending] = []

    def flush() -> None:
        buf = np.concatenate([p.data for p in pending]) if len(pending) > 1 else pending[0].data
        base = np.cumsum([0] + [len(p.data) for p in pending[:-1]])
        offset = np.concatenate([p.offset + b for p, b in zip(pending, base)])
        size, topic = np.concatenate([p.size for p in pending]), np.concatenate([p.topic for p in pending])
        log_time = np.concatenate([p.log_time for p in pending])
        position = np.concatenate([p.position for p in pending])
        for k in np.nonzero(np.bincount(topic, minlength=len(topics)))[0].tolist():
            sel = np.nonzero(topic == k)[0]
            parts[topics[k]].append((decode(topics[k], buf, offset[sel], size[sel]), log_time[sel], position[sel]))
        pending.clear()

    def end_of_file() -> None:
        # rosbags' order within a file: (log_time, chunk offset, position in the chunk)
        for topic in topics:
            if parts[topic]:
                rows, log_time, position = (np.concatenate(x) for x in zip(*parts[topic]))
                keys = [log_time, position]
                out[topic].append(rows if len(rows) < 2 or _in_order(keys) else rows[np.lexsort(keys[::-1])])
                parts[topic].clear()

    held = 0
    for mf in files:   # rosbags reads the files of a bag one after the other
        if not mf.topics:
            continue
        storage = mf.storage
        assert isinstance(storage, McapReader)   # read_topics calls this for MCAP storage files only
        lut = np.full(max(mf.topics) + 1, -1, np.int64)   # channel id -> topic index
        for cid, t in mf.topics.items():
            lut[cid] = topics.index(t)
        rank = {c.chunk_start_offset: i for i, c in enumerate(sorted(storage.chunks,
                                                                     key=lambda c: c.chunk_start_offset))}
        with storage.path.open("rb") as f:
            for chunk in storage.chunks:
                # the chunks rosbags' McapReader.messages reads: those indexing a wanted channel
                if not any(chunk.channel_count.get(cid, 0) for cid in mf.topics):
                    continue
                if chunk.uncompressed_size >= 1 << 32:
                    raise IndexMismatch("chunk of 4 GiB or more")
                data, area = read_chunk(f, chunk)
                m = chunk_messages(data, chunk, area)
                topic = np.where(m.channel < len(lut), lut[np.minimum(m.channel, len(lut) - 1)], -1)
                keep = np.nonzero((topic >= 0) & (m.log_time >= chunk.message_start_time)
                                  & (m.log_time <= chunk.message_end_time))[0]
                position = m.offset[keep].astype(np.uint64) | np.uint64(rank[chunk.chunk_start_offset] << 32)
                pending.append(_Pending(m.data, m.offset[keep] + RECORD_HEAD + MESSAGE_HEAD, m.size[keep],
                                        topic[keep], m.log_time[keep], position))
                held += len(data)
                if held >= batch_bytes:
                    flush()
                    held = 0
        if pending:
            flush()
            held = 0
        end_of_file()
    return {t: np.concatenate(r) for t, r in out.items() if r}


def _read_rows(rows: Iterator[tuple[Any, ...]], topic_of: Callable[[Any], str], decode: Decode,
               batch: int) -> dict[str, list[np.ndarray]]:
    """Decode ``(key, timestamp, data)`` rows in blocks of ``batch``: per block one joined
    buffer, the topic of each row ``topic_of(key)``; C-level loops only (zip, map, join)."""
    out: dict[str, list[np.ndarray]] = {}
    while block := list(islice(rows, batch)):
        keys, _, datas = zip(*block)
        del block
        names = list(map(topic_of, keys))
        topics = list(dict.fromkeys(names))
        code = {t: i for i, t in enumerate(topics)}
        tix = np.fromiter(map(code.__getitem__, names), np.int64, len(names))
        sizes = np.fromiter(map(len, datas), np.int64, len(datas))
        buf = b"".join(datas)
        del datas
        offsets = np.cumsum(sizes) - sizes
        for k, topic in enumerate(topics):
            sel = np.nonzero(tix == k)[0]
            out.setdefault(topic, []).append(decode(topic, buf, offsets[sel], sizes[sel]))
    return out


def _read_sqlite(files: list[StorageFile], decode: Decode, batch: int) -> dict[str, list[np.ndarray]]:
    out: dict[str, list[np.ndarray]] = {}
    for sf in files:
        if not sf.topics:
            continue
        ids = tuple(sf.topics)
        storage = sf.storage
        # read_topics calls this for sqlite3 storage files with a connection only (an open reader's)
        assert isinstance(storage, Sqlite3Reader) and storage.dbconn is not None
        # the query of rosbags' Sqlite3Reader.messages, whose row order we must keep
        query = ("SELECT topics.id,messages.timestamp,messages.data FROM messages JOIN topics ON "
                 f"messages.topic_id=topics.id WHERE topics.id IN ({','.join('?' for _ in ids)}) "
                 "ORDER BY timestamp")
        for topic, rows in _read_rows(iter(storage.dbconn.execute(query, ids)), sf.topics.__getitem__,
                                      decode, batch).items():
            out.setdefault(topic, []).extend(rows)
    return out


def read_topics(reader: AnyReader, connections: Sequence[Connection], decode: Decode,
                batch: int = BATCH, batch_bytes: int = BATCH_BYTES) -> dict[str, np.ndarray]:
    """Decoded rows of every message of ``connections``, per topic, in rosbags' order.

    reader: an open AnyReader.  connections: some of ``reader.connections``.  decode: see
    :data:`Decode`; called once per topic for every ``batch_bytes`` of decompressed MCAP
    chunks, or for every ``batch`` messages otherwise.  Returns topic -> (n, c) rows,
    concatenated in the order ``reader.messages(connections=connections)`` yields the
    topic's messages; topics without messages are absent.

    Raises rosbags' ReaderError/AnyReaderError for an unreadable bag and whatever
    ``decode`` raises.
    """
    files = storage_files(reader, connections)
    if files is not None and all(isinstance(f.storage, McapReader) for f in files) and all(
            hasattr(f.storage, "chunks") and (f.storage.chunks or not f.topics) for f in files):
        try:
            return _read_mcap(files, decode, batch_bytes)
        except IndexMismatch:
            pass   # read it as rosbags does, message by message (in blocks)
    if files is not None and all(isinstance(f.storage, Sqlite3Reader) and hasattr(f.storage, "dbconn")
                                 for f in files):
        parts = _read_sqlite(files, decode, batch)
    else:
        parts = _read_rows(reader.messages(connections=connections), attrgetter("topic"), decode, batch)
    return {topic: np.concatenate(rows) for topic, rows in parts.items()}


__all__ = ["Decode", "StorageFile", "ChunkMessages", "IndexMismatch", "chunk_messages", "read_chunk", "storage_files",
           "read_topics", "BATCH", "BATCH_BYTES"]
