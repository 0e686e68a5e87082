"""A properly closed MCAP file read from its summary: schemas, channels, statistics and chunk indexes, which
cost the same whatever the file's size; each topic's time range from the message indexes of the chunks at
its ends; message heads gathered with numpy through the message indexes. Every offset the summary gives is
checked against the file before it is followed."""
from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Iterator
from io import BufferedReader
from pathlib import Path

import numpy as np
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import ChunkIndex

from epuck_ros.bag.contents import BagError, Topic
from epuck_ros.bag.mcap_records import MAGIC, MESSAGE_FIELDS, MESSAGE_HEAD, U64, chunk_records, make_topic, \
    rosbag2_metadata_in

_FOOTER = struct.Struct('<BQQQI')  # opcode, length, summary start, summary offset start, summary crc
_INDEX_HEAD = struct.Struct('<HI')


class McapIndex:
    """What a file's summary section says; `load` tells whether it has a usable one."""

    def __init__(self, path: Path, data: mmap.mmap, size: int) -> None:
        self.path, self._map, self.size = path, data, size
        self.topics: dict[int, Topic] = {}
        self.rosbag2_metadata: dict = {}
        self.profile, self.library = '', ''
        self.problem: str | None = None
        """Why a file with a footer must be scanned instead (None: it has no footer, or no summary to read)."""
        self.indexes: list[ChunkIndex] = []
        """The chunk indexes in file order."""

    @property
    def chunks(self) -> list[tuple[int, frozenset[int] | None]]:
        """(offset, channels) of each chunk; a chunk without message indexes may hold any channel (None)."""
        return [(c.chunk_start_offset, frozenset(c.message_index_offsets) or None) for c in self.indexes]

    def load(self, handle: BufferedReader) -> bool:
        """Read the summary; False (scan the file instead) when there is no footer or no usable summary."""
        footer = self._footer()
        return bool(footer) and self._load_summary(handle, *footer)

    def _footer(self) -> tuple[int, int, int] | None:
        """(footer offset, summary start, summary crc) when the file ends with a footer and the magic."""
        footer = self.size - len(MAGIC) - _FOOTER.size
        if footer < len(MAGIC) or self._map[-len(MAGIC):] != MAGIC:
            return None
        opcode, length, summary_start, _, crc = _FOOTER.unpack_from(self._map, footer)
        if (opcode, length) != (Opcode.FOOTER, _FOOTER.size - 9):
            return None
        return footer, summary_start, crc

    def _load_summary(self, handle: BufferedReader, footer: int, summary_start: int, crc: int) -> bool:
        """Topics and statistics from the summary section; False (scan instead) when it has none or it is corrupt."""
        if summary_start == 0:
            return False
        if not len(MAGIC) < summary_start <= footer:
            self.problem = f'summary start {summary_start} outside the file'
            return False
        if crc and zlib.crc32(self._map[summary_start:footer + _FOOTER.size - 4]) != crc:
            self.problem = 'summary section fails its CRC'
            return False
        handle.seek(0)
        try:
            reader = SeekingReader(handle)
            header = reader.get_header()
            summary = reader.get_summary()
        except (McapError, struct.error, ValueError, EOFError, KeyError, IndexError, OverflowError) as error:
            self.problem = f'unreadable summary section ({error or type(error).__name__})'
            return False
        if summary is None or (summary.statistics is None or not summary.chunk_indexes
                               and summary.statistics.message_count):
            return False
        indexes = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        self.problem = self._check_chunk_indexes(indexes)
        if self.problem is not None:
            return False
        self.profile, self.library = header.profile, header.library
        for channel in summary.channels.values():
            self.topics[channel.id] = make_topic(channel, summary.schemas, self.path)
        self.indexes = indexes
        statistics = summary.statistics
        for channel_id, count in statistics.channel_message_counts.items():
            if count and channel_id in self.topics:
                first, last = self._time_range(channel_id)
                self.topics[channel_id].add_times(count, statistics.message_start_time if first is None else first,
                                                  statistics.message_end_time if last is None else last)
        for index in summary.metadata_indexes:
            if index.name == 'rosbag2':
                self._keep_rosbag2_metadata(index.offset)
        return True

    def _keep_rosbag2_metadata(self, offset: int) -> None:
        try:
            body = self._record_body(offset, Opcode.METADATA, f'{self.path} metadata record')
        except BagError:
            return  # optional (it gives the ROS distro): a corrupt one is ignored
        document = rosbag2_metadata_in(body, self.path, offset)
        if document is not None:
            self.rosbag2_metadata = document

    def _check_chunk_indexes(self, indexes: list[ChunkIndex]) -> str | None:
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
        (length,) = U64.unpack_from(self._map, offset + 1)
        if offset + 9 + length > self.size:
            raise BagError(f'{what} at byte {offset}: runs past the end of the file')
        return memoryview(self._map)[offset + 9:offset + 9 + length]

    def _time_range(self, channel_id: int) -> tuple[int | None, int | None]:
        """First and last log_time of a channel from the message indexes of the chunks at the ends (None without)."""
        chunks = [c for c in self.indexes if channel_id in c.message_index_offsets]
        first, last = None, None
        for chunk in sorted(chunks, key=lambda c: c.message_start_time):
            if first is not None and chunk.message_start_time >= first:
                break
            earliest = int(self._index_entries(chunk, channel_id)[:, 0].min(initial=chunk.message_end_time))
            first = earliest if first is None else min(first, earliest)
        for chunk in sorted(chunks, key=lambda c: -c.message_end_time):
            if last is not None and chunk.message_end_time <= last:
                break
            latest = int(self._index_entries(chunk, channel_id)[:, 0].max(initial=chunk.message_start_time))
            last = latest if last is None else max(last, latest)
        return first, last

    def _index_entries(self, chunk: ChunkIndex, channel_id: int) -> np.ndarray:
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

    def message_heads(self, channel_ids: frozenset[int], width: int) -> Iterator[tuple[int, np.ndarray]]:
        """(channel id, (n, width) uint8 array) per chunk: the first `width` data bytes of each message of a
        channel, in file order, found through the message indexes (every chunk must have them); shorter
        messages are left out."""
        columns = np.arange(width)
        for index in self.indexes:
            wanted = [c for c in channel_ids if c in index.message_index_offsets]
            if not wanted:
                continue
            records = np.frombuffer(chunk_records(self._map, self.path, index.chunk_start_offset, self.size),
                                    np.uint8)
            for channel_id in wanted:
                offsets, lengths = self._messages(index, channel_id, records)
                offsets = offsets[lengths >= MESSAGE_FIELDS + width]
                yield channel_id, records[offsets[:, None] + MESSAGE_HEAD + columns]

    def _messages(self, index: ChunkIndex, channel_id: int, records: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(offsets, body lengths) of a channel's Message records in a chunk's records, in file order, checked
        against the records."""
        where = f'{self.path}: message index of the chunk at byte {index.chunk_start_offset}'
        offsets = np.sort(self._index_entries(index, channel_id)[:, 1])
        if len(offsets) and int(offsets[-1]) + MESSAGE_HEAD > len(records):
            raise BagError(f'{where} points past its records')
        offsets = offsets.astype(np.int64)
        heads = records[offsets[:, None] + np.arange(MESSAGE_HEAD)]
        lengths = heads[:, 1:9].copy().view('<u8')[:, 0]
        channels = heads[:, 9:11].copy().view('<u2')[:, 0]
        if np.any(heads[:, 0] != Opcode.MESSAGE) or np.any(channels != channel_id) or \
                np.any(offsets + 9 + lengths.astype(np.int64) > len(records)):
            raise BagError(f'{where} does not match its records')
        return offsets, lengths
