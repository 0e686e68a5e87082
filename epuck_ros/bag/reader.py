"""Reading rosbag2 MCAP bags without ROS: a bag folder (metadata.yaml and its files) or a single ``.mcap`` file.

A properly closed file is opened from its summary (`mcap_index`), a file without one is scanned, and messages
are walked chunk by chunk (`mcap_file`), their records decoded by `mcap_records`. Bags are untrusted input:
every length is checked against the bytes that hold it before it is used, chunk CRCs are verified,
decompressed sizes and YAML documents are bounded, and anything wrong raises `BagError` naming the file and the
place — never a traceback, never made-up data. The names a reader of bags needs are all importable from here.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import replace
from pathlib import Path, PurePath

import numpy as np

from epuck_ros.bag.contents import MAX_METADATA_BYTES, MAX_YAML_DEPTH, BagError, BagMessage, RawMessage, Topic, \
    load_yaml
from epuck_ros.bag.mcap_file import McapFile
from epuck_ros.bag.mcap_records import MAGIC, MAX_CHUNK_BYTES, MESSAGE_HEAD

__all__ = ['MAGIC', 'MAX_CHUNK_BYTES', 'MAX_METADATA_BYTES', 'MAX_YAML_DEPTH', 'MESSAGE_HEAD', 'Bag', 'BagError',
           'BagMessage', 'McapFile', 'RawMessage', 'Topic', 'load_yaml']


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
