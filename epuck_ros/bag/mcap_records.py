"""MCAP records from untrusted bytes: the layouts, one record's body, a chunk's records (decompressed and
checked), a header's strings, a channel as a `Topic`. Every length is checked against the bytes that hold
it before it is used, and anything wrong raises `BagError` naming the file and the place."""
from __future__ import annotations

import struct
import zlib
from io import BytesIO
from pathlib import Path

import lz4.frame
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Metadata, Schema

from epuck_ros.bag.contents import BagError, Topic, rosbag2_metadata

MAGIC = b'\x89MCAP0\r\n'
RECORD = struct.Struct('<BQ')
"""Every record's head: opcode, body length."""
MESSAGE = struct.Struct('<BQHIQQ')
"""A Message record's head: opcode, length, channel id, sequence, log time, publish time."""
MESSAGE_FIELDS = 2 + 4 + 8 + 8
"""Bytes of a Message record's body before its data."""
MESSAGE_HEAD = MESSAGE.size
"""Bytes from a Message record's opcode to its data."""
_CHUNK = struct.Struct('<QQQII')  # start time, end time, uncompressed size, uncompressed crc, name length
_U32 = struct.Struct('<I')
U64 = struct.Struct('<Q')
MAX_CHUNK_BYTES = 256 * 2**20
"""Largest decompressed chunk accepted (rosbag2 writes 768 KiB chunks): a corrupt size cannot cost GBs."""


def read_record(body: bytes, cls: type, where: str) -> object:
    """Parse one record body (after opcode and length) with mcap's record classes."""
    try:
        return cls.read(ReadDataStream(BytesIO(body)))
    except (McapError, struct.error, ValueError, EOFError) as error:
        raise BagError(f'{where}: corrupt {cls.__name__} record ({error or type(error).__name__})') from None


def rosbag2_metadata_in(body: bytes, path: Path, offset: int) -> dict | None:
    """The document of a metadata record's body at `offset` if it is rosbag2's, else None: the record is optional
    (it gives the ROS distro), so a corrupt one is ignored."""
    try:
        record = read_record(body, Metadata, f'{path} at byte {offset}')
    except BagError:
        return None
    return rosbag2_metadata(record, str(path))


def decompress(compression: str, data: memoryview, size: int, where: str) -> bytes | memoryview:
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


def chunk_records(data: bytes, path: Path, offset: int, limit: int) -> bytes | memoryview:
    """The records of the chunk at `offset` (ending by `limit`), decompressed and checked against its CRC."""
    where = f'{path}: chunk at byte {offset}'
    if offset + 9 + _CHUNK.size > limit or data[offset] != Opcode.CHUNK:
        raise BagError(f'{where}: no chunk there')
    (length,) = U64.unpack_from(data, offset + 1)
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
    (records_length,) = U64.unpack_from(data, position)
    if position + 8 + records_length > end:
        raise BagError(f'{where}: its records run past the end of the chunk')
    records = memoryview(data)[position + 8:position + 8 + records_length]
    buffer = decompress(compression, records, size, where)
    if crc and zlib.crc32(buffer) != crc:
        raise BagError(f'{where}: chunk fails its CRC (the file is corrupt)')
    return buffer


def header_strings(data: bytes, path: Path, offset: int, end: int, count: int) -> list[str]:
    """The first `count` length-prefixed strings of a Header record's body (profile, library)."""
    found = []
    for _ in range(count):
        if offset + 4 > end:
            raise BagError(f'{path}: header record cut short at byte {offset}')
        (length,) = _U32.unpack_from(data, offset)
        if offset + 4 + length > end:
            raise BagError(f'{path}: header record cut short at byte {offset}')
        found.append(data[offset + 4:offset + 4 + length].decode('utf-8', 'replace'))
        offset += 4 + length
    return found


def make_topic(channel: Channel, schemas: dict[int, Schema], path: Path) -> Topic:
    """A channel and its schema as a `Topic` (without statistics yet)."""
    schema = schemas.get(channel.schema_id)
    if schema is None and channel.schema_id != 0:  # 0: a channel without schema (MCAP allows it)
        raise BagError(f'{path}: topic {channel.topic} has no schema (id {channel.schema_id})')
    return Topic(channel.topic, schema.name if schema else '', schema.encoding if schema else '',
                 schema.data.decode('utf-8', 'replace') if schema else '',
                 channel.metadata.get('offered_qos_profiles', ''), channel.metadata.get('topic_type_hash', ''),
                 message_encoding=channel.message_encoding)
