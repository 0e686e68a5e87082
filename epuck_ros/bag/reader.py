"""Reading rosbag2 MCAP bags without ROS: a bag folder or a single ``.mcap`` file.

A properly closed file is opened from its summary (schemas, channels, statistics, chunk
indexes), which costs the same whatever the file's size. A file without a footer (a recorder
killed outright), or whose summary fails its CRC, is scanned instead, and every *complete*
chunk is read; what follows the last complete record is ignored. The file is memory-mapped and
messages come out as offsets into the (decompressed) chunk, so callers that decode a few fields
never copy a message.

Bags are untrusted input: every length is checked against the bytes that hold it before it is
used, chunk CRCs are verified, decompressed sizes and YAML documents are bounded, and anything
wrong raises `BagError` naming the file and the place — never a traceback, never made-up data.
"""
from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from io import BytesIO
from pathlib import Path, PurePath
from typing import NamedTuple

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import Channel, Metadata, Schema

from epuck_ros import untrusted_yaml

MAGIC = b'\x89MCAP0\r\n'
_RECORD = struct.Struct('<BQ')
_MESSAGE = struct.Struct('<BQHIQQ')
_MESSAGE_FIELDS = 2 + 4 + 8 + 8
_CHUNK = struct.Struct('<QQQII')  # start time, end time, uncompressed size, uncompressed crc, name length
_FOOTER = struct.Struct('<BQQQI')  # opcode, length, summary start, summary offset start, summary crc
_INDEX_HEAD = struct.Struct('<HI')
_U32 = struct.Struct('<I')
_U64 = struct.Struct('<Q')
MESSAGE_HEAD = _MESSAGE.size
"""Bytes from a Message record's opcode to its data."""
MAX_CHUNK_BYTES = 256 * 2**20
"""Largest decompressed chunk accepted (rosbag2 writes 768 KiB chunks): a corrupt size cannot cost GBs."""
MAX_METADATA_BYTES = 2**20
"""Largest metadata.yaml / rosbag2 metadata record parsed; rosbag2's own are a few KiB."""
MAX_YAML_DEPTH = 32
"""Deepest nesting accepted in metadata YAML (rosbag2's is 5 levels)."""


class RawMessage(NamedTuple):
    """One message as the file holds it: the CDR bytes are buffer[start:end], and the buffer ends with the
    message, so a decoder reading too far fails instead of reading the next one."""

    topic: str
    log_time: int
    """ns; when the recorder received it."""
    publish_time: int
    """ns; when the publisher sent it (rosbag2 writes the receive time here too)."""
    buffer: memoryview
    start: int
    end: int


class BagError(Exception):
    """A bag that cannot be read; the message names the file and what is wrong with it."""


@dataclass
class Topic:
    """A topic as the bag holds it: channel metadata, schema and message statistics."""

    name: str
    type_name: str
    schema_encoding: str
    schema_text: str
    offered_qos_profiles: str
    type_hash: str
    message_count: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    message_encoding: str = 'cdr'
    """The channel's message encoding as the file says it (``cdr`` for ROS 2, ``json``, ...)."""

    def add_times(self, count: int, first: int, last: int) -> None:
        self.message_count += count
        self.first_ns = first if self.first_ns is None else min(self.first_ns, first)
        self.last_ns = last if self.last_ns is None else max(self.last_ns, last)

    @property
    def frequency(self) -> float | None:
        """Mean message rate in Hz, from the first and last log_time."""
        if self.message_count < 2 or self.last_ns == self.first_ns:
            return None
        return (self.message_count - 1) * 1e9 / (self.last_ns - self.first_ns)


@dataclass(frozen=True)
class BagMessage:
    topic: str
    log_time: int
    publish_time: int
    data: bytes


def load_yaml(text: str, where: str) -> object:
    """A YAML document from an untrusted file: no aliases (no expansion bombs), bounded nesting."""
    try:
        return untrusted_yaml.load(text, MAX_YAML_DEPTH)
    except untrusted_yaml.UntrustedYamlError as error:
        raise BagError(f'{where}: {error}') from None


def _read_record(body: bytes, cls: type, where: str) -> object:
    """Parse one record body (after opcode and length) with mcap's record classes."""
    try:
        return cls.read(ReadDataStream(BytesIO(body)))
    except (McapError, struct.error, ValueError, EOFError) as error:
        raise BagError(f'{where}: corrupt {cls.__name__} record ({error or type(error).__name__})') from None


def _decompress(compression: str, data: memoryview, size: int, where: str) -> bytes | memoryview:
    """A chunk's records, exactly `size` bytes (the size its header declares, bounded by MAX_CHUNK_BYTES)."""
    if size > MAX_CHUNK_BYTES:
        raise BagError(f'{where}: chunk declares {size} uncompressed bytes (more than {MAX_CHUNK_BYTES})')
    try:
        if compression == '':
            result = data
        elif compression == 'zstd':
            framed = zstandard.frame_content_size(data)
            if framed not in (-1, size):
                raise BagError(f'{where}: zstd frame holds {framed} bytes, the chunk header says {size}')
            result = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        elif compression == 'lz4':
            framed = lz4.frame.get_frame_info(data).get('content_size') or size
            if framed != size:
                raise BagError(f'{where}: lz4 frame holds {framed} bytes, the chunk header says {size}')
            result = lz4.frame.decompress(data)
        else:
            raise BagError(f'{where}: unsupported chunk compression {compression!r}')
    except (zstandard.ZstdError, RuntimeError, ValueError) as error:
        raise BagError(f'{where}: corrupt {compression} chunk ({error})') from None
    if len(result) != size:
        raise BagError(f'{where}: chunk holds {len(result)} bytes of records, its header says {size}')
    return result


class McapFile:
    """One MCAP file of a bag: its topics, statistics, and an iterator over its messages."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._handle = open(path, 'rb')
            self.size = path.stat().st_size
        except OSError as error:
            raise BagError(f'{path}: {error.strerror}') from None
        head = self._handle.read(len(MAGIC))
        if not head or head != MAGIC[:len(head)]:
            self._handle.close()
            raise BagError(f'{path}: not an MCAP file (no MCAP magic at the start)')
        if self.size < len(MAGIC) + 9:
            self._handle.close()
            raise BagError(f'{path}: truncated MCAP file ({self.size} bytes, not even a header)')
        self._map = mmap.mmap(self._handle.fileno(), 0, access=mmap.ACCESS_READ)
        self.topics: dict[int, Topic] = {}
        self.rosbag2_metadata: dict = {}
        self.profile, self.library = '', ''
        self.summary_problem: str | None = None
        """Why a file with a footer was scanned instead of read from its summary (None: it was not)."""
        self._chunks: list[tuple[int, frozenset[int] | None]] | None = None
        """(offset, channels) of each chunk, from the summary; None: scan the file instead."""
        self._indexes: list = []
        self.ignored_bytes = 0
        """Bytes after the last complete record of a file that was not closed properly."""
        try:
            footer = self._footer()
            if footer and self._load_summary(*footer):
                self.closed_properly = True
                return
            self.closed_properly = False
            self._scan()
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        try:
            self._map.close()
        except BufferError:
            pass  # a message view still exists (e.g. in a traceback); the map closes when it goes
        self._handle.close()

    # -- opening ------------------------------------------------------------------------------

    def _footer(self) -> tuple[int, int, int] | None:
        """(footer offset, summary start, summary crc) when the file ends with a footer and the magic."""
        footer = self.size - len(MAGIC) - _FOOTER.size
        if footer < len(MAGIC) or self._map[-len(MAGIC):] != MAGIC:
            return None
        opcode, length, summary_start, _, crc = _FOOTER.unpack_from(self._map, footer)
        if (opcode, length) != (Opcode.FOOTER, _FOOTER.size - 9):
            return None
        return footer, summary_start, crc

    def _load_summary(self, footer: int, summary_start: int, crc: int) -> bool:
        """Topics and statistics from the summary section; False (scan instead) when it has none or it is corrupt."""
        if summary_start == 0:
            return False
        if not len(MAGIC) < summary_start <= footer:
            self.summary_problem = f'summary start {summary_start} outside the file'
            return False
        if crc and zlib.crc32(self._map[summary_start:footer + _FOOTER.size - 4]) != crc:
            self.summary_problem = 'summary section fails its CRC'
            return False
        self._handle.seek(0)
        try:
            reader = SeekingReader(self._handle)
            header = reader.get_header()
            summary = reader.get_summary()
        except (McapError, struct.error, ValueError, EOFError, KeyError, IndexError, OverflowError) as error:
            self.summary_problem = f'unreadable summary section ({error or type(error).__name__})'
            return False
        if summary is None or (summary.statistics is None or not summary.chunk_indexes
                               and summary.statistics.message_count):
            return False
        indexes = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        problem = self._check_chunk_indexes(indexes)
        if problem is not None:
            self.summary_problem = problem
            return False
        self.profile, self.library = header.profile, header.library
        for channel in summary.channels.values():
            self.topics[channel.id] = self._topic(channel, summary.schemas)
        self._indexes = indexes
        # A chunk without message indexes may hold any channel (None: always read it).
        self._chunks = [(c.chunk_start_offset, frozenset(c.message_index_offsets) or None) for c in self._indexes]
        statistics = summary.statistics
        for channel_id, count in statistics.channel_message_counts.items():
            if count and channel_id in self.topics:
                first, last = self._time_range(channel_id)
                self.topics[channel_id].add_times(count, statistics.message_start_time if first is None else first,
                                                  statistics.message_end_time if last is None else last)
        for index in summary.metadata_indexes:
            if index.name == 'rosbag2':
                try:
                    body = self._record_body(index.offset, Opcode.METADATA, f'{self.path} metadata record')
                    self._keep_rosbag2_metadata(_read_record(body, Metadata, f'{self.path} at byte {index.offset}'))
                except BagError:
                    pass  # optional (it gives the ROS distro): a corrupt one is ignored
        return True

    def _check_chunk_indexes(self, indexes: list) -> str | None:
        """What is wrong with the summary's chunk indexes (each must point at a chunk and its message indexes)."""
        for index in indexes:
            offset = index.chunk_start_offset
            if offset + 9 > self.size or self._map[offset] != Opcode.CHUNK:
                return f'chunk index points at byte {offset}, where no chunk starts'
            for message_index in index.message_index_offsets.values():
                if message_index + 9 + _INDEX_HEAD.size > self.size:
                    return f'message index offset {message_index} outside the file'
        return None

    def _record_body(self, offset: int, opcode: int, what: str) -> memoryview:
        """The body of the record at `offset`, which must be of the given kind and lie inside the file."""
        if offset + 9 > self.size or self._map[offset] != opcode:
            raise BagError(f'{what} at byte {offset}: no such record there')
        (length,) = _U64.unpack_from(self._map, offset + 1)
        if offset + 9 + length > self.size:
            raise BagError(f'{what} at byte {offset}: runs past the end of the file')
        return memoryview(self._map)[offset + 9:offset + 9 + length]

    def _time_range(self, channel_id: int) -> tuple[int | None, int | None]:
        """First and last log_time of a channel from the message indexes of the chunks at the ends (None without)."""
        chunks = [c for c in self._indexes if channel_id in c.message_index_offsets]
        first, last = None, None
        for chunk in sorted(chunks, key=lambda c: c.message_start_time):
            if first is not None and chunk.message_start_time >= first:
                break
            earliest = int(self._index_times(chunk, channel_id).min(initial=chunk.message_end_time))
            first = earliest if first is None else min(first, earliest)
        for chunk in sorted(chunks, key=lambda c: -c.message_end_time):
            if last is not None and chunk.message_end_time <= last:
                break
            latest = int(self._index_times(chunk, channel_id).max(initial=chunk.message_start_time))
            last = latest if last is None else max(last, latest)
        return first, last

    def _index_times(self, chunk: object, channel_id: int) -> np.ndarray:
        """The log_times of a channel's Message Index record in a chunk."""
        return self._index_entries(chunk, channel_id)[:, 0]

    def _index_entries(self, chunk: object, channel_id: int) -> np.ndarray:
        """A Message Index record as (log_time, offset) rows, checked against its chunk."""
        offset = chunk.message_index_offsets[channel_id]
        body = self._record_body(offset, Opcode.MESSAGE_INDEX, f'{self.path}: message index')
        indexed_channel, length = _INDEX_HEAD.unpack_from(body)
        if indexed_channel != channel_id or length % 16 or _INDEX_HEAD.size + length > len(body):
            raise BagError(f'{self.path}: message index at byte {offset} is corrupt')
        entries = np.frombuffer(body, dtype='<u8', count=length // 8, offset=_INDEX_HEAD.size).reshape(-1, 2)
        times = entries[:, 0]
        if len(times) and (times.min() < chunk.message_start_time or times.max() > chunk.message_end_time):
            raise BagError(f'{self.path}: message index at byte {offset} has times outside its chunk')
        return entries

    def _scan(self) -> None:
        """Without a summary: walk every complete record once to find topics and counts."""
        self._chunks = None
        counts: dict[str, list[int]] = {}
        for name, log_time, *_ in self._walk(None):
            entry = counts.get(name)
            if entry is None:
                counts[name] = [1, log_time, log_time]
            else:
                entry[0] += 1
                entry[1] = min(entry[1], log_time)
                entry[2] = max(entry[2], log_time)
        for topic in self.topics.values():
            if topic.name in counts:
                topic.add_times(*counts[topic.name])

    def _topic(self, channel: Channel, schemas: dict[int, Schema]) -> Topic:
        schema = schemas.get(channel.schema_id)
        if schema is None and channel.schema_id != 0:  # 0: a channel without schema (MCAP allows it)
            raise BagError(f'{self.path}: topic {channel.topic} has no schema (id {channel.schema_id})')
        return Topic(channel.topic, schema.name if schema else '', schema.encoding if schema else '',
                     schema.data.decode('utf-8', 'replace') if schema else '',
                     channel.metadata.get('offered_qos_profiles', ''), channel.metadata.get('topic_type_hash', ''),
                     message_encoding=channel.message_encoding)

    def _keep_rosbag2_metadata(self, record: Metadata) -> None:
        """rosbag2's metadata record (for the ROS distro); an unreadable one is ignored, as it is optional."""
        text = record.metadata.get('serialized_metadata', '') if record.name == 'rosbag2' else ''
        if not text or len(text) > MAX_METADATA_BYTES:
            return
        try:
            document = load_yaml(text, str(self.path))
        except BagError:
            return
        self.rosbag2_metadata = document if isinstance(document, dict) else {}

    # -- reading ------------------------------------------------------------------------------

    def iter_raw(self, channel_ids: frozenset[int] | None = None) -> Iterator[RawMessage]:
        """Messages of some channels (all when None) in file order."""
        if self._chunks is None:
            yield from self._walk(channel_ids)
            return
        for offset, channels in self._chunks:
            if channel_ids is None or channels is None or not channels.isdisjoint(channel_ids):
                yield from self._walk_chunk(offset, self.size, channel_ids)

    def _walk(self, channel_ids: frozenset[int] | None) -> Iterator[tuple]:
        """Top-level records from the start; stops at the data end or at the first incomplete record.

        A chunk that does not check out (CRC, size) also ends the readable part: in a file without a usable
        summary that is the chunk being written when the writer died, its pages never written (zeros)."""
        data, size = self._map, self.size
        schemas: dict[int, Schema] = {}
        position = len(MAGIC)
        while position < size:
            opcode, length = _RECORD.unpack_from(data, position) if position + 9 <= size else (0, size)
            end = position + 9 + length
            if end > size or opcode == 0:  # cut short, or zeros (a crash can leave a zero-filled tail)
                self.ignored_bytes = size - position
                break
            if opcode in (Opcode.FOOTER, Opcode.DATA_END):
                break
            if opcode == Opcode.CHUNK:
                try:
                    records = self._chunk_records(position, end)
                except BagError:
                    self.ignored_bytes = size - position
                    break
                yield from self._walk_records(records, 0, len(records), channel_ids, schemas, position)
            elif opcode == Opcode.HEADER:
                self.profile, self.library = self._strings(position + 9, end, 2)
            elif opcode == Opcode.METADATA:
                try:
                    self._keep_rosbag2_metadata(_read_record(data[position + 9:end], Metadata,
                                                             f'{self.path} at byte {position}'))
                except BagError:
                    pass  # optional (it gives the ROS distro): a corrupt one is ignored
            else:
                yield from self._walk_records(data, position, end, channel_ids, schemas, position)
            position = end

    def _strings(self, offset: int, end: int, count: int) -> list[str]:
        found = []
        for _ in range(count):
            if offset + 4 > end:
                raise BagError(f'{self.path}: header record cut short at byte {offset}')
            (length,) = _U32.unpack_from(self._map, offset)
            if offset + 4 + length > end:
                raise BagError(f'{self.path}: header record cut short at byte {offset}')
            found.append(self._map[offset + 4:offset + 4 + length].decode('utf-8', 'replace'))
            offset += 4 + length
        return found

    def _walk_chunk(self, offset: int, limit: int, channel_ids: frozenset[int] | None) -> Iterator[tuple]:
        """The messages of the chunk record at `offset`, which must end by `limit`."""
        buffer = self._chunk_records(offset, limit)
        yield from self._walk_records(buffer, 0, len(buffer), channel_ids, {}, offset)

    def _chunk_records(self, offset: int, limit: int) -> bytes | memoryview:
        """The records of the chunk at `offset` (ending by `limit`), decompressed and checked against its CRC."""
        data, where = self._map, f'{self.path}: chunk at byte {offset}'
        if offset + 9 + _CHUNK.size > limit or data[offset] != Opcode.CHUNK:
            raise BagError(f'{where}: no chunk there')
        (length,) = _U64.unpack_from(data, offset + 1)
        end = offset + 9 + length
        if end > limit:
            raise BagError(f'{where}: runs past the end of the file')
        _, _, size, crc, name_length = _CHUNK.unpack_from(data, offset + 9)
        position = offset + 9 + _CHUNK.size
        if position + name_length + 8 > end:
            raise BagError(f'{where}: corrupt chunk header')
        try:
            compression = data[position:position + name_length].decode()
        except UnicodeDecodeError:
            raise BagError(f'{where}: corrupt chunk header (compression name is not text)') from None
        position += name_length
        (records_length,) = _U64.unpack_from(data, position)
        if position + 8 + records_length > end:
            raise BagError(f'{where}: its records run past the end of the chunk')
        records = memoryview(data)[position + 8:position + 8 + records_length]
        buffer = _decompress(compression, records, size, where)
        if crc and zlib.crc32(buffer) != crc:
            raise BagError(f'{where}: chunk fails its CRC (the file is corrupt)')
        return buffer

    def message_heads(self, channel_ids: frozenset[int], width: int) -> Iterator[tuple[int, np.ndarray]]:
        """(channel id, array of shape (n, width)): the first `width` data bytes of each message of a channel,
        in file order, one array per chunk. Gathered with numpy through the message indexes when the summary
        has them (a million stamps in a fraction of a second), else by walking; shorter messages are left out."""
        if self._chunks is None or any(channels is None for _, channels in self._chunks):
            heads: dict[int, list[bytes]] = {}
            names = {self.topics[c].name: c for c in channel_ids if c in self.topics}
            for name, _, _, buffer, start, end in self.iter_raw(channel_ids):
                if end - start >= width:
                    heads.setdefault(names[name], []).append(bytes(buffer[start:start + width]))
            for channel_id, rows in heads.items():
                yield channel_id, np.frombuffer(b''.join(rows), np.uint8).reshape(-1, width)
            return
        columns = np.arange(width)
        for index in self._indexes:
            wanted = [c for c in channel_ids if c in index.message_index_offsets]
            if not wanted:
                continue
            records = np.frombuffer(self._chunk_records(index.chunk_start_offset, self.size), np.uint8)
            for channel_id in wanted:
                offsets = np.sort(self._index_entries(index, channel_id)[:, 1])
                if len(offsets) and int(offsets[-1]) + MESSAGE_HEAD > len(records):
                    raise BagError(f'{self.path}: message index of the chunk at byte {index.chunk_start_offset} '
                                   'points past its records')
                offsets = offsets.astype(np.int64)
                heads = records[offsets[:, None] + np.arange(MESSAGE_HEAD)]
                lengths = heads[:, 1:9].copy().view('<u8')[:, 0]
                channels = heads[:, 9:11].copy().view('<u2')[:, 0]
                if np.any(heads[:, 0] != Opcode.MESSAGE) or np.any(channels != channel_id) or \
                        np.any(offsets + 9 + lengths.astype(np.int64) > len(records)):
                    raise BagError(f'{self.path}: message index of the chunk at byte {index.chunk_start_offset} '
                                   'does not match its records')
                offsets = offsets[lengths >= _MESSAGE_FIELDS + width]
                yield channel_id, records[offsets[:, None] + MESSAGE_HEAD + columns]

    def _walk_records(self, buffer: bytes, position: int, end: int, channel_ids: frozenset[int] | None,
                      schemas: dict[int, Schema], where: int) -> Iterator[RawMessage]:
        """Messages between two offsets of a buffer; schemas and channels met on the way are registered.

        Each message comes with a view of the buffer that ends where the message does.
        """
        unpack_message, unpack_record = _MESSAGE.unpack_from, _RECORD.unpack_from
        new_message = tuple.__new__   # RawMessage without its Python-level __new__: half the cost per message
        topics, view = self.topics, memoryview(buffer)
        while position < end:
            if buffer[position] == Opcode.MESSAGE and position + MESSAGE_HEAD <= end:
                _, length, channel_id, _, log_time, publish_time = unpack_message(buffer, position)
                record_end = position + 9 + length
                if record_end > end or length < _MESSAGE_FIELDS:
                    raise BagError(f'{self.path}: record {position} bytes into the chunk or file part at byte '
                                   f'{where} runs past its end')
                if channel_ids is None or channel_id in channel_ids:
                    topic = topics.get(channel_id)
                    if topic is None:
                        raise BagError(f'{self.path}: a message at byte {where} + {position} is on channel '
                                       f'{channel_id}, which the file does not define')
                    yield new_message(RawMessage, (topic.name, log_time, publish_time, view[:record_end],
                                                   position + MESSAGE_HEAD, record_end))
                position = record_end
                continue
            if position + 9 > end:
                raise BagError(f'{self.path}: record cut short {position} bytes into the part at byte {where}')
            opcode, length = unpack_record(buffer, position)
            record_end = position + 9 + length
            if record_end > end or opcode in (Opcode.MESSAGE, 0):
                raise BagError(f'{self.path}: record {position} bytes into the chunk or file part at byte '
                               f'{where} runs past its end')
            if opcode == Opcode.SCHEMA:
                schema = _read_record(buffer[position + 9:record_end], Schema, f'{self.path} at byte {where}')
                schemas[schema.id] = schema
            elif opcode == Opcode.CHANNEL and self._chunks is None:
                channel = _read_record(buffer[position + 9:record_end], Channel, f'{self.path} at byte {where}')
                topics.setdefault(channel.id, self._topic(channel, schemas))
            position = record_end


class Bag:
    """A bag folder (files listed in metadata.yaml, else every ``*.mcap``) or a single ``.mcap`` file."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise BagError(f'{self.path}: no such bag folder or file')
        if not self.path.is_dir() and not self.path.is_file():
            raise BagError(f'{self.path}: neither a bag folder nor a regular file')
        self.files: list[McapFile] = []
        try:
            for file_path in self._file_paths():
                self.files.append(McapFile(file_path))
        except BaseException:
            self.close()
            raise
        self.topics: dict[str, Topic] = {}
        for file in self.files:
            for topic in file.topics.values():
                merged = self.topics.setdefault(topic.name, replace(topic, message_count=0, first_ns=None,
                                                                    last_ns=None))
                if topic.message_count:
                    merged.add_times(topic.message_count, topic.first_ns, topic.last_ns)

    def _file_paths(self) -> list[Path]:
        if self.path.is_file():
            return [self.path]
        metadata = self.path / 'metadata.yaml'
        if metadata.is_file():
            paths = [self.path / name for name in _relative_file_paths(metadata)]
            missing = [str(p) for p in paths if not p.is_file()]
            if missing:
                raise BagError(f'{metadata} lists files that do not exist: {", ".join(missing)}')
            return paths
        paths = sorted(p for p in self.path.glob('*.mcap') if p.is_file())
        if not paths:
            raise BagError(f'{self.path}: no .mcap file in this folder')
        return paths

    def __enter__(self) -> Bag:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for file in self.files:
            file.close()

    @property
    def closed_properly(self) -> bool:
        return all(f.closed_properly for f in self.files)

    @property
    def message_count(self) -> int:
        return sum(t.message_count for t in self.topics.values())

    @property
    def start_ns(self) -> int | None:
        return min((t.first_ns for t in self.topics.values() if t.message_count), default=None)

    @property
    def end_ns(self) -> int | None:
        return max((t.last_ns for t in self.topics.values() if t.message_count), default=None)

    @property
    def size(self) -> int:
        return sum(f.size for f in self.files)

    def topics_of_type(self, type_name: str) -> list[Topic]:
        """CDR topics of a ROS type that have messages."""
        return [t for t in self.topics.values()
                if t.type_name == type_name and t.message_count and t.message_encoding == 'cdr']

    def iter_raw(self, topics: Iterable[str] | None = None) -> Iterator[RawMessage]:
        """Messages of some topics (all when None) without copying: decode ``buffer[start:end]``."""
        wanted = None if topics is None else set(topics)
        for file in self.files:
            ids = None if wanted is None else frozenset(c for c, t in file.topics.items() if t.name in wanted)
            yield from file.iter_raw(ids)

    def message_heads(self, topics: Iterable[str], width: int) -> dict[str, np.ndarray]:
        """{topic: (n, width) uint8 array}: the first `width` data bytes of every message, in file order."""
        wanted = set(topics)
        found: dict[str, list[np.ndarray]] = {}
        for file in self.files:
            ids = frozenset(c for c, t in file.topics.items() if t.name in wanted)
            for channel_id, heads in file.message_heads(ids, width):
                found.setdefault(file.topics[channel_id].name, []).append(heads)
        return {name: np.concatenate(parts) for name, parts in found.items()}

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
        for topic, log_time, publish_time, buffer, start, end in self.iter_raw(topics):
            yield BagMessage(topic, log_time, publish_time, bytes(buffer[start:end]))


def _relative_file_paths(metadata: Path) -> list[str]:
    """The MCAP files a metadata.yaml lists, each a plain relative name."""
    try:
        size = metadata.stat().st_size
        if size > MAX_METADATA_BYTES:
            raise BagError(f'{metadata}: {size} bytes, too large for a rosbag2 metadata file '
                           f'(at most {MAX_METADATA_BYTES})')
        data = metadata.read_bytes()
    except OSError as error:
        raise BagError(f'{metadata}: {error.strerror}') from None
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as error:
        raise BagError(f'{metadata}: not a text file (byte {error.start} is not UTF-8)') from None
    document = load_yaml(text, str(metadata))
    info = document.get('rosbag2_bagfile_information') if isinstance(document, dict) else None
    names = info.get('relative_file_paths') if isinstance(info, dict) else None
    if not isinstance(names, list) or not all(isinstance(n, str) and n for n in names):
        raise BagError(f'{metadata}: not a rosbag2 metadata file (no rosbag2_bagfile_information.'
                       'relative_file_paths list of file names)')
    for name in names:
        if PurePath(name).is_absolute() or '..' in PurePath(name).parts or '\0' in name:
            raise BagError(f'{metadata}: relative_file_paths entry {name!r} is not a file inside the bag folder')
    return names
