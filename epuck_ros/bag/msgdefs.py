"""Message definitions as rosbag2 embeds them: the ``ros2msg`` schema text and the RIHS01 type hash.

The text is built exactly as rosbag2's ``LocalMessageDefinitionSource`` does (Jazzy): the raw
``.msg`` file, then every dependency depth-first, each preceded by a line of 80 ``=`` and
``MSG: pkg/Type`` (the name as written in the field). Readers (rosbags, mcap_ros2, Foxglove)
need the full closure to decode, and rosbags checks the hash against the embedded text.
"""
from __future__ import annotations

import json
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path

PRIMITIVE_TYPES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string'))
"""rosbag2's list; ``wstring`` is not in it, as in rosbag2."""

_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
"""rosbag2's MSG_FIELD_TYPE_REGEX: the first word of a line is a field's type."""

SEPARATOR = '=' * 80


class MessageDefinitionError(LookupError):
    """A message type whose definition cannot be found or is malformed."""


@dataclass(frozen=True)
class MessageDefinition:
    """What a bag stores about one message type."""

    name: str
    encoding: str
    text: str
    type_hash: str


def interface_prefixes() -> list[Path]:
    """Install prefixes holding ``share/<pkg>/msg``: AMENT_PREFIX_PATH, else this Python's prefix."""
    ament = os.environ.get('AMENT_PREFIX_PATH', '')
    prefixes = [Path(p) for p in ament.split(os.pathsep) if p]
    return prefixes or [Path(sys.prefix)]


def split_type_name(type_name: str) -> tuple[str, str]:
    """``pkg/msg/Type`` or ``pkg/Type`` -> (pkg, Type)."""
    parts = type_name.split('/')
    if len(parts) == 3 and parts[1] == 'msg':
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise MessageDefinitionError(f'{type_name!r} is not a message type name like pkg/msg/Type')


def _interface_file(type_name: str, extension: str) -> Path | None:
    package, name = split_type_name(type_name)
    for prefix in interface_prefixes():
        candidate = prefix / 'share' / package / 'msg' / f'{name}.{extension}'
        if candidate.is_file():
            return candidate
    return None


def _msg_text(type_name: str) -> str:
    path = _interface_file(type_name, 'msg')
    if path is None:
        searched = ', '.join(str(p) for p in interface_prefixes())
        raise MessageDefinitionError(f'no .msg file for {type_name} under {searched}')
    with open(path, encoding='utf-8', newline='') as handle:
        return handle.read()


def _dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types, package-qualified, sorted as rosbag2's std::set orders them."""
    found = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in PRIMITIVE_TYPES:
            continue
        found.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(found)


def schema_text(type_name: str) -> str:
    """The full ``ros2msg`` text of ``pkg/msg/Type``, byte-identical to rosbag2's."""
    seen: set[str] = set()

    def with_dependencies(name: str) -> str:
        text = _msg_text(name)
        for dependency in _dependencies(text, split_type_name(name)[0]):
            if dependency not in seen:
                seen.add(dependency)
                text += f'\n{SEPARATOR}\nMSG: {dependency}\n' + with_dependencies(dependency)
        return text

    return with_dependencies(type_name)


def type_hash(type_name: str) -> str:
    """RIHS01 hash from the installed ``<T>.json`` type description; '' when unknown (as rosbag2)."""
    path = _interface_file(type_name, 'json')
    if path is None:
        return ''
    package, name = split_type_name(type_name)
    full_name = f'{package}/msg/{name}'
    for entry in json.loads(path.read_text(encoding='utf-8')).get('type_hashes', []):
        if entry.get('type_name') == full_name:
            return entry.get('hash_string', '')
    return ''


def message_definition(type_name: str) -> MessageDefinition:
    """Schema and hash for a channel; encoding 'unknown' and no text when no .msg exists (as rosbag2)."""
    try:
        return MessageDefinition(type_name, 'ros2msg', schema_text(type_name), type_hash(type_name))
    except MessageDefinitionError:
        return MessageDefinition(type_name, 'unknown', '', '')
