"""What reading a bag hands out: its topics and messages, the error for a bag that cannot be read, and the
bounded parsing of the YAML a bag carries (metadata.yaml, the rosbag2 metadata record)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from mcap.records import Metadata

from epuck_ros import untrusted_yaml

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


def rosbag2_metadata(record: Metadata, where: str) -> dict | None:
    """The document of rosbag2's metadata record (it gives the ROS distro); None for another record, or one
    too large or unreadable: it is optional, so a bad one is ignored rather than failing the bag."""
    text = record.metadata.get('serialized_metadata', '') if record.name == 'rosbag2' else ''
    if not text or len(text) > MAX_METADATA_BYTES:
        return None
    try:
        document = load_yaml(text, where)
    except BagError:
        return None
    return document if isinstance(document, dict) else {}
