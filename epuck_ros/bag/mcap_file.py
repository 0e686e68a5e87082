"""One MCAP file of a bag: opened from its summary (`McapIndex`) when it was closed properly, else scanned;
its messages walked chunk by chunk and record by record.

A file without a footer (a recorder killed outright), or whose summary fails its CRC, is scanned, and every
*complete* chunk is read; what follows the last complete record is ignored. The file is memory-mapped and
messages come out as offsets into the (decompressed) chunk, so callers that decode a few fields never copy a
message.
"""
from __future__ import annotations

import mmap
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from mcap.opcode import Opcode
from mcap.records import Channel, Schema

from epuck_ros.bag.contents import BagError, RawMessage, Topic
from epuck_ros.bag.mcap_index import McapIndex
from epuck_ros.bag.mcap_records import MAGIC, MESSAGE, MESSAGE_FIELDS, MESSAGE_HEAD, RECORD, chunk_records, \
    header_strings, make_topic, read_record, rosbag2_metadata_in


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
        self.ignored_bytes = 0
        """Bytes after the last complete record of a file that was not closed properly."""
        try:
            self._open()
        except BaseException:
            self.close()
            raise

    def _open(self) -> None:
        """Topics and statistics from the summary, or from a scan of every complete record."""
        index = McapIndex(self.path, self._map, self.size)
        self.closed_properly = index.load(self._handle)
        self.summary_problem = index.problem
        """Why a file with a footer was scanned instead of read from its summary (None: it was not)."""
        if self.closed_properly:
            self.topics, self.rosbag2_metadata = index.topics, index.rosbag2_metadata
            self.profile, self.library = index.profile, index.library
            self._index: McapIndex | None = index
            self._chunks = index.chunks
            """(offset, channels) of each chunk, from the summary; None: scan the file instead."""
            return
        self.topics: dict[int, Topic] = {}
        self.rosbag2_metadata: dict = {}
        self.profile, self.library = '', ''
        self._index, self._chunks = None, None
        self._scan()

    def close(self) -> None:
        try:
            self._map.close()
        except BufferError:
            pass  # a message view still exists (e.g. in a traceback); the map closes when it goes
        self._handle.close()

    def _scan(self) -> None:
        """Without a summary: walk every complete record once to find topics and counts."""
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

    def iter_raw(self, channel_ids: frozenset[int] | None = None) -> Iterator[RawMessage]:
        """Messages of some channels (all when None) in file order."""
        if self._chunks is None:
            yield from self._walk(channel_ids)
            return
        for offset, channels in self._chunks:
            if channel_ids is None or channels is None or not channels.isdisjoint(channel_ids):
                buffer = chunk_records(self._map, self.path, offset, self.size)
                yield from self._walk_records(buffer, 0, len(buffer), channel_ids, {}, offset)

    def message_heads(self, channel_ids: frozenset[int], width: int) -> Iterator[tuple[int, np.ndarray]]:
        """(channel id, array of shape (n, width)): the first `width` data bytes of each message of a channel,
        in file order, one array per chunk. Gathered with numpy through the message indexes when the summary
        has them (a million stamps in a fraction of a second), else by walking; shorter messages are left out."""
        if self._index is not None and all(channels is not None for _, channels in self._chunks):
            yield from self._index.message_heads(channel_ids, width)
            return
        heads: dict[int, list[bytes]] = {}
        names = {self.topics[c].name: c for c in channel_ids if c in self.topics}
        for name, _, _, buffer, start, end in self.iter_raw(channel_ids):
            if end - start >= width:
                heads.setdefault(names[name], []).append(bytes(buffer[start:start + width]))
        for channel_id, rows in heads.items():
            yield channel_id, np.frombuffer(b''.join(rows), np.uint8).reshape(-1, width)

    def _walk(self, channel_ids: frozenset[int] | None) -> Iterator[RawMessage]:
        """Top-level records from the start; stops at the data end or at the first incomplete record.

        A chunk that does not check out (CRC, size) also ends the readable part: in a file without a usable
        summary that is the chunk being written when the writer died, its pages never written (zeros)."""
        data, size = self._map, self.size
        schemas: dict[int, Schema] = {}
        position = len(MAGIC)
        while position < size:
            opcode, length = RECORD.unpack_from(data, position) if position + 9 <= size else (0, size)
            end = position + 9 + length
            if end > size or opcode == 0:  # cut short, or zeros (a crash can leave a zero-filled tail)
                self.ignored_bytes = size - position
                break
            if opcode in (Opcode.FOOTER, Opcode.DATA_END):
                break
            if opcode == Opcode.CHUNK:
                try:
                    records = chunk_records(data, self.path, position, end)
                except BagError:
                    self.ignored_bytes = size - position
                    break
                yield from self._walk_records(records, 0, len(records), channel_ids, schemas, position)
            elif opcode == Opcode.HEADER:
                self.profile, self.library = header_strings(data, self.path, position + 9, end, 2)
            elif opcode == Opcode.METADATA:
                self._keep_rosbag2_metadata(data[position + 9:end], position)
            else:
                yield from self._walk_records(data, position, end, channel_ids, schemas, position)
            position = end

    def _keep_rosbag2_metadata(self, body: bytes, offset: int) -> None:
        document = rosbag2_metadata_in(body, self.path, offset)
        if document is not None:
            self.rosbag2_metadata = document

    def _walk_records(self, buffer: bytes, position: int, end: int, channel_ids: frozenset[int] | None,
                      schemas: dict[int, Schema], where: int) -> Iterator[RawMessage]:
        """Messages between two offsets of a buffer; schemas and channels met on the way are registered.

        Each message comes with a view of the buffer that ends where the message does.
        """
        unpack_message, unpack_record = MESSAGE.unpack_from, RECORD.unpack_from
        new_message = tuple.__new__   # RawMessage without its Python-level __new__: half the cost per message
        topics, view = self.topics, memoryview(buffer)
        while position < end:
            if buffer[position] == Opcode.MESSAGE and position + MESSAGE_HEAD <= end:
                _, length, channel_id, _, log_time, publish_time = unpack_message(buffer, position)
                record_end = position + 9 + length
                if record_end > end or length < MESSAGE_FIELDS:
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
                schema = read_record(buffer[position + 9:record_end], Schema, f'{self.path} at byte {where}')
                schemas[schema.id] = schema
            elif opcode == Opcode.CHANNEL and self._chunks is None:
                channel = read_record(buffer[position + 9:record_end], Channel, f'{self.path} at byte {where}')
                topics.setdefault(channel.id, make_topic(channel, schemas, self.path))
            position = record_end
