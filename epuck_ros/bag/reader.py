"""Reading rosbag2 MCAP bags without ROS: a bag folder or a single ``.mcap`` file.

A properly closed file is opened from its summary (schemas, channels, statistics, chunk
indexes), which costs the same whatever the file's size. A file without a footer (a recorder
killed outright) is scanned instead, and every *complete* chunk is read; what follows the last
complete record is ignored. The file is memory-mapped and messages come out as offsets into
the (decompressed) chunk, so callers that decode a few fields never copy a message.
"""
from __future__ import annotations

import mmap
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from io import BytesIO
from pathlib import Path

import lz4.frame
import numpy as np
import yaml
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import Channel, Metadata, Schema

MAGIC = b'\x89MCAP0\r\n'
_RECORD = struct.Struct('<BQ')
_MESSAGE = struct.Struct('<BQHIQQ')
_CHUNK = struct.Struct('<QQQII')
_INDEX_HEAD = struct.Struct('<HI')
_FOOTER_SIZE = 9 + 20
MESSAGE_HEAD = _MESSAGE.size
"""Bytes from a Message record's opcode to its data."""

RawMessage = tuple[str, int, int, bytes, int, int]
"""(topic, log_time ns, publish_time ns, buffer, data start, data end): the CDR bytes are buffer[start:end]."""


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


def _read_record(body: bytes, cls: type) -> object:
    """Parse one record body (after opcode and length) with mcap's record classes."""
    return cls.read(ReadDataStream(BytesIO(body)))


def _decompress(compression: str, data: memoryview, size: int, where: str) -> bytes | memoryview:
    try:
        if compression == '':
            return data
        if compression == 'zstd':
            return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        if compression == 'lz4':
            return lz4.frame.decompress(data)
    except (zstandard.ZstdError, RuntimeError) as error:
        raise BagError(f'{where}: corrupt {compression} chunk ({error})') from None
    raise BagError(f'{where}: unsupported chunk compression {compression!r}')


class McapFile:
    """One MCAP file of a bag: its topics, statistics, and an iterator over its messages."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._handle = open(path, 'rb')
        except OSError as error:
            raise BagError(f'{path}: {error.strerror}') from None
        self.size = path.stat().st_size
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
        self.closed_properly = self._has_footer()
        self._chunks: list[tuple[int, frozenset[int] | None]] | None = None
        """(offset, channels) of each chunk, from the summary; None: scan the file instead."""
        self._indexes: list = []
        self.ignored_bytes = 0
        """Bytes after the last complete record of a file that was not closed properly."""
        if self.closed_properly and self._load_summary():
            return
        self._scan()

    def close(self) -> None:
        try:
            self._map.close()
        except BufferError:
            pass  # a message view still exists (e.g. in a traceback); the map closes when it goes
        self._handle.close()

    # -- opening ------------------------------------------------------------------------------

    def _has_footer(self) -> bool:
        footer = self.size - len(MAGIC) - _FOOTER_SIZE
        return (self.size >= 2 * len(MAGIC) + _FOOTER_SIZE and self._map[-len(MAGIC):] == MAGIC
                and _RECORD.unpack_from(self._map, footer) == (Opcode.FOOTER, 20))

    def _load_summary(self) -> bool:
        """Topics and statistics from the summary section; False when the file has none."""
        self._handle.seek(0)
        reader = SeekingReader(self._handle)
        try:
            header = reader.get_header()
            summary = reader.get_summary()
        except (McapError, struct.error, ValueError) as error:
            raise BagError(f'{self.path}: unreadable summary section ({error})') from None
        if summary is None or (summary.statistics is None or not summary.chunk_indexes
                               and summary.statistics.message_count):
            return False
        self.profile, self.library = header.profile, header.library
        for channel in summary.channels.values():
            self.topics[channel.id] = self._topic(channel, summary.schemas)
        self._indexes = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
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
                body = self._map[index.offset + 9:index.offset + index.length]
                self._keep_rosbag2_metadata(_read_record(body, Metadata))
        return True

    def _time_range(self, channel_id: int) -> tuple[int | None, int | None]:
        """First and last log_time of a channel from the message indexes of the chunks at the ends (None without)."""
        chunks = [c for c in self._indexes if channel_id in c.message_index_offsets]
        first, last = None, None
        for chunk in sorted(chunks, key=lambda c: c.message_start_time):
            if first is not None and chunk.message_start_time >= first:
                break
            earliest = int(self._index_times(chunk.message_index_offsets[channel_id]).min())
            first = earliest if first is None else min(first, earliest)
        for chunk in sorted(chunks, key=lambda c: -c.message_end_time):
            if last is not None and chunk.message_end_time <= last:
                break
            latest = int(self._index_times(chunk.message_index_offsets[channel_id]).max())
            last = latest if last is None else max(last, latest)
        return first, last

    def _index_times(self, offset: int) -> np.ndarray:
        """The log_times of a Message Index record (entries are log_time, offset pairs)."""
        _, length = _INDEX_HEAD.unpack_from(self._map, offset + 9)
        start = offset + 9 + _INDEX_HEAD.size
        return np.frombuffer(self._map, dtype='<u8', count=length // 8, offset=start)[::2]

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
        if schema is None:
            raise BagError(f'{self.path}: topic {channel.topic} has no schema (id {channel.schema_id})')
        return Topic(channel.topic, schema.name, schema.encoding, schema.data.decode('utf-8', 'replace'),
                     channel.metadata.get('offered_qos_profiles', ''), channel.metadata.get('topic_type_hash', ''))

    def _keep_rosbag2_metadata(self, record: Metadata) -> None:
        if record.name == 'rosbag2':
            try:
                self.rosbag2_metadata = yaml.safe_load(record.metadata.get('serialized_metadata', '')) or {}
            except yaml.YAMLError:
                self.rosbag2_metadata = {}

    # -- reading ------------------------------------------------------------------------------

    def iter_raw(self, channel_ids: frozenset[int] | None = None) -> Iterator[RawMessage]:
        """Messages of some channels (all when None) in file order."""
        if self._chunks is None:
            yield from self._walk(channel_ids)
            return
        for offset, channels in self._chunks:
            if channel_ids is None or channels is None or not channels.isdisjoint(channel_ids):
                yield from self._walk_chunk(offset, channel_ids)

    def _walk(self, channel_ids: frozenset[int] | None) -> Iterator[tuple]:
        """Top-level records from the start; stops at the footer or at the first incomplete record."""
        data, size = self._map, self.size
        schemas: dict[int, Schema] = {}
        position = len(MAGIC)
        while position < size:
            opcode, length = _RECORD.unpack_from(data, position) if position + 9 <= size else (0, size)
            end = position + 9 + length
            if end > size:
                self.ignored_bytes = size - position
                break
            if opcode == Opcode.FOOTER:
                break
            if opcode == Opcode.CHUNK:
                yield from self._walk_chunk(position, channel_ids, schemas)
            elif opcode == Opcode.HEADER:
                self.profile, self.library = self._strings(position + 9, 2)
            elif opcode == Opcode.METADATA:
                self._keep_rosbag2_metadata(_read_record(data[position + 9:end], Metadata))
            else:
                yield from self._walk_records(data, position, end, channel_ids, schemas)
            position = end

    def _strings(self, offset: int, count: int) -> list[str]:
        found = []
        for _ in range(count):
            (length,) = struct.unpack_from('<I', self._map, offset)
            found.append(self._map[offset + 4:offset + 4 + length].decode('utf-8', 'replace'))
            offset += 4 + length
        return found

    def _walk_chunk(self, offset: int, channel_ids: frozenset[int] | None,
                    schemas: dict[int, Schema] | None = None) -> Iterator[tuple]:
        data = self._map
        _, _, size, _, name_length = _CHUNK.unpack_from(data, offset + 9)
        position = offset + 9 + _CHUNK.size
        compression = data[position:position + name_length].decode()
        position += name_length
        (records_length,) = struct.unpack_from('<Q', data, position)
        records = memoryview(data)[position + 8:position + 8 + records_length]
        where = f'{self.path} chunk at byte {offset}'
        buffer = _decompress(compression, records, size, where)
        yield from self._walk_records(buffer, 0, len(buffer), channel_ids, schemas if schemas is not None else {})

    def _walk_records(self, buffer: bytes, position: int, end: int, channel_ids: frozenset[int] | None,
                      schemas: dict[int, Schema]) -> Iterator[tuple]:
        """Messages between two offsets of a buffer; schemas and channels met on the way are registered."""
        unpack_message, unpack_record = _MESSAGE.unpack_from, _RECORD.unpack_from
        topics = self.topics
        while position < end:
            if buffer[position] == Opcode.MESSAGE:
                _, length, channel_id, _, log_time, publish_time = unpack_message(buffer, position)
                if channel_ids is None or channel_id in channel_ids:
                    yield (topics[channel_id].name, log_time, publish_time,
                           buffer, position + MESSAGE_HEAD, position + 9 + length)
            else:
                opcode, length = unpack_record(buffer, position)
                if opcode == Opcode.SCHEMA:
                    schema = _read_record(buffer[position + 9:position + 9 + length], Schema)
                    schemas[schema.id] = schema
                elif opcode == Opcode.CHANNEL and self._chunks is None:
                    channel = _read_record(buffer[position + 9:position + 9 + length], Channel)
                    topics.setdefault(channel.id, self._topic(channel, schemas))
            position += 9 + length


class Bag:
    """A bag folder (files listed in metadata.yaml, else every ``*.mcap``) or a single ``.mcap`` file."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise BagError(f'{self.path}: no such bag folder or file')
        self.files = [McapFile(p) for p in self._file_paths()]
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
            try:
                info = yaml.safe_load(metadata.read_text())['rosbag2_bagfile_information']
                paths = [self.path / name for name in info['relative_file_paths']]
            except (yaml.YAMLError, KeyError, TypeError) as error:
                raise BagError(f'{metadata}: not a rosbag2 metadata file ({error})') from None
            missing = [str(p) for p in paths if not p.is_file()]
            if missing:
                raise BagError(f'{metadata} lists files that do not exist: {", ".join(missing)}')
            return paths
        paths = sorted(self.path.glob('*.mcap'))
        if not paths:
            raise BagError(f'{self.path}: no .mcap file in this folder')
        return paths

    def __enter__(self) -> Bag:
        return self

    def __exit__(self, *exc: object) -> None:
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
        return [t for t in self.topics.values() if t.type_name == type_name and t.message_count]

    def iter_raw(self, topics: Iterable[str] | None = None) -> Iterator[RawMessage]:
        """Messages of some topics (all when None) without copying: decode ``buffer[start:end]``."""
        wanted = None if topics is None else set(topics)
        for file in self.files:
            ids = None if wanted is None else frozenset(c for c, t in file.topics.items() if t.name in wanted)
            yield from file.iter_raw(ids)

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
        for topic, log_time, publish_time, buffer, start, end in self.iter_raw(topics):
            yield BagMessage(topic, log_time, publish_time, bytes(buffer[start:end]))
