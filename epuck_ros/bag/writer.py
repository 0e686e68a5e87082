"""Writing rosbag2 bags: a folder with ``<name>_0.mcap`` and ``metadata.yaml`` (version 9).

`BagWriter` follows ``shared/reference/rosbag2-mcap.md``: profile ``ros2``, one ``ros2msg``
schema per type, ``cdr`` channels carrying ``offered_qos_profiles`` and ``topic_type_hash``,
chunks with message indexes, the ``rosbag2`` metadata record at open and at close. Every
completed chunk goes straight to the OS, so a recorder killed outright leaves a file whose
complete chunks are still readable, and so does a write that fails (a full disk): the file is
then left as it is, without a summary and without metadata.yaml, which `bag info` reads up to its
last complete chunk. `BackgroundWriter` moves the writing to its own thread so subscription
callbacks only enqueue.
"""
from __future__ import annotations

import functools
import os
import queue
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from mcap.writer import CompressionType, IndexType, Writer

from epuck_ros.bag.msgdefs import message_definition
from epuck_ros.bag.qos import QosProfile, dump_yaml, profiles_to_yaml

COMPRESSIONS = {'none': CompressionType.NONE, 'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4}
CHUNK_SIZE = 768 * 1024
"""rosbag2's default chunk size."""
NO_MESSAGES_START_NS = 2**63 - 1
"""rosbag2's starting_time before the first message (INT64_MAX)."""
LIBRARY = 'epuck_ros bag writer (mcap python)'
ROS_DISTRO = os.environ.get('ROS_DISTRO', 'jazzy')
"""This package targets Jazzy; the venv from PyPI wheels does not set ROS_DISTRO."""


class BagExistsError(FileExistsError):
    """The output folder already exists: recording never overwrites a bag."""


class BagWriteError(RuntimeError):
    """Writing the bag failed (a full disk, a file size limit); what was written before stays readable."""


@dataclass
class TopicRecord:
    """What the bag knows about one topic, and how many messages it got."""

    name: str
    type_name: str
    qos_profiles: list[QosProfile]
    type_hash: str
    channel_id: int
    message_count: int = 0

    def metadata(self) -> dict:
        return {
            'topic_metadata': {
                'name': self.name,
                'type': self.type_name,
                'serialization_format': 'cdr',
                'offered_qos_profiles': [p.to_dict() for p in self.qos_profiles],
                'type_description_hash': self.type_hash,
            },
            'message_count': self.message_count,
        }


@dataclass
class TimeRange:
    """First and last log_time seen, in nanoseconds."""

    start: int = NO_MESSAGES_START_NS
    end: int = 0
    count: int = 0

    def add(self, stamp: int) -> None:
        self.start = min(self.start, stamp)
        self.end = max(self.end, stamp)
        self.count += 1

    @property
    def duration(self) -> int:
        return self.end - self.start if self.count else 0


class _DirectFile:
    """A write-only file without a Python-side buffer.

    mcap's writer wraps raw files in a BufferedWriter; a kill would then lose completed chunks
    still in that buffer. It writes only whole records (a chunk and its indexes at once), so
    unbuffered writes cost a few system calls per chunk.
    """

    def __init__(self, path: Path) -> None:
        self._file = open(path, 'xb', buffering=0)

    def write(self, data: bytes) -> int:
        view = memoryview(data)
        while view:
            view = view[self._file.write(view):]
        return len(data)

    def tell(self) -> int:
        return self._file.tell()

    def flush(self) -> None:
        """Nothing is buffered here."""

    def close(self) -> None:
        self._file.close()


class BagWriter:
    """Writes one bag folder; `close()` finishes the MCAP summary and writes metadata.yaml."""

    def __init__(self, path: str | Path, compression: str = 'none', chunk_size: int = CHUNK_SIZE) -> None:
        if compression not in COMPRESSIONS:
            raise ValueError(f'compression must be one of {", ".join(COMPRESSIONS)}, not {compression!r}')
        self.path = Path(path)
        try:
            self.path.mkdir(parents=True)
        except FileExistsError:
            raise BagExistsError(f'{self.path} already exists; choose another output name') from None
        self.file_name = f'{self.path.name}_0.mcap'
        self._file = _DirectFile(self.path / self.file_name)
        self._mcap = Writer(self._file, chunk_size=chunk_size, compression=COMPRESSIONS[compression],
                            index_types=IndexType.ALL)
        self._mcap.start(profile='ros2', library=LIBRARY)
        self._schemas: dict[str, int] = {}
        self.topics: dict[str, TopicRecord] = {}
        self.times = TimeRange()
        self._mcap.add_metadata('rosbag2', {'serialized_metadata': dump_yaml(self.metadata())})
        self._closed = False

    def add_topic(self, name: str, type_name: str, qos_profiles: list[QosProfile]) -> TopicRecord:
        """Register a channel (and its type's schema once); the QoS list is stored as offered."""
        if name in self.topics:
            return self.topics[name]
        definition = message_definition(type_name)
        if type_name not in self._schemas:
            self._schemas[type_name] = self._mcap.register_schema(
                type_name, definition.encoding, definition.text.encode('utf-8'))
        channel_id = self._mcap.register_channel(name, 'cdr', self._schemas[type_name], {
            'offered_qos_profiles': profiles_to_yaml(qos_profiles),
            'topic_type_hash': definition.type_hash,
        })
        topic = TopicRecord(name, type_name, list(qos_profiles), definition.type_hash, channel_id)
        self.topics[name] = topic
        return topic

    def write(self, topic: str, data: bytes, log_time: int, publish_time: int | None = None) -> None:
        """Add one CDR message (with its encapsulation header) to a topic added before."""
        record = self.topics[topic]
        self._mcap.add_message(record.channel_id, log_time, data,
                               log_time if publish_time is None else publish_time)
        record.message_count += 1
        self.times.add(log_time)

    def flush(self) -> None:
        """End the chunk in progress and hand it to the OS, so a kill after this loses nothing."""
        self._mcap.flush()

    def metadata(self) -> dict:
        """rosbag2's BagMetadata (v9) for what has been written so far."""
        file_entry = {
            'path': self.file_name,
            'starting_time': {'nanoseconds_since_epoch': self.times.start},
            'duration': {'nanoseconds': self.times.duration},
            'message_count': self.times.count,
        }
        return {
            'version': 9,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': self.times.duration},
            'starting_time': {'nanoseconds_since_epoch': self.times.start},
            'message_count': self.times.count,
            'topics_with_message_count': [t.metadata() for t in self.topics.values()],
            # Compression happens inside the MCAP chunks (like rosbag2's zstd storage presets),
            # not rosbag2's file compression, so these stay empty.
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.file_name],
            'files': [file_entry],
            'custom_data': None,
            'ros_distro': ROS_DISTRO,
        }

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._mcap.flush()
            metadata = self.metadata()
            self._mcap.add_metadata('rosbag2', {'serialized_metadata': dump_yaml(metadata)})
            self._mcap.finish()
        finally:
            self._file.close()
        # Written whole or not at all: a half-written metadata.yaml would hide the readable MCAP file.
        partial = self.path / 'metadata.yaml.part'
        try:
            partial.write_text(dump_yaml({'rosbag2_bagfile_information': metadata}), encoding='utf-8')
            os.replace(partial, self.path / 'metadata.yaml')
        finally:
            partial.unlink(missing_ok=True)

    def abort(self) -> None:
        """Stop after a failed write: close the file as it is (its complete chunks stay readable)."""
        self._closed = True
        self._file.close()


_STOP = object()


class BackgroundWriter:
    """Owns a `BagWriter` in a thread: callers enqueue, the thread writes and flushes every `flush_period` s.

    Enqueuing is all a subscription callback pays, so bursts (eight Range messages per step)
    never wait for a chunk being written. Thread-safe for any number of producers.
    """

    def __init__(self, writer: BagWriter, flush_period: float = 1.0) -> None:
        self.writer = writer
        self._flush_period = flush_period
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name='bag_writer', daemon=True)
        self._thread.start()

    def add_topic(self, name: str, type_name: str, qos_profiles: list[QosProfile]) -> None:
        self._queue.put(functools.partial(self.writer.add_topic, name, type_name, list(qos_profiles)))

    @property
    def error(self) -> BaseException | None:
        """What made writing fail, if it did; messages written after that are dropped."""
        return self._error

    def write(self, topic: str, data: bytes, log_time: int, publish_time: int | None = None) -> None:
        if self._error is None:
            self._queue.put((topic, data, log_time, publish_time))

    def flush(self, timeout: float | None = None) -> bool:
        """Write everything queued so far in complete chunks (a kill after this loses none of it).

        Returns False if that did not happen within `timeout` seconds or writing has failed."""
        done = threading.Event()
        self._queue.put(done)
        return done.wait(timeout) and self._error is None

    def close(self) -> None:
        """Write everything queued, finish the bag; raises BagWriteError if writing failed at any point."""
        self._queue.put(_STOP)
        self._thread.join()
        if self._error is not None:
            raise BagWriteError(f'bag writing failed: {self._error}') from self._error

    def _run(self) -> None:
        try:
            self._drain()
        except BaseException as error:  # kept for the producer: a thread cannot raise to it
            self._error = error
            self.writer.abort()
            return
        try:
            self.writer.close()
        except BaseException as error:
            self._error = error

    def _drain(self) -> None:
        writer, get = self.writer, self._queue.get
        unflushed, next_flush = False, time.monotonic() + self._flush_period
        while True:
            try:
                item = get(timeout=max(0.0, next_flush - time.monotonic()))
            except queue.Empty:
                item = None
            if item is _STOP:
                return
            if isinstance(item, tuple):
                writer.write(*item)
                unflushed = True
            elif isinstance(item, functools.partial):   # add_topic, run in this thread as the writes are
                item()
            elif isinstance(item, threading.Event):
                writer.flush()
                unflushed = False
                item.set()
            if time.monotonic() >= next_flush:
                if unflushed:
                    writer.flush()
                unflushed, next_flush = False, time.monotonic() + self._flush_period
