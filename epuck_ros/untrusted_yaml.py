"""YAML we did not write (world files, a bag's `world` topic, `metadata.yaml`, QoS profiles) loaded at bounded cost.

A few hundred bytes of aliases expand to gigabytes, and thousands of nested brackets exhaust the stack; both are
refused on libyaml's event stream, before any Python object is built, so the check costs little whatever the input.
The error names the field being read when the offending node appears (`robots[0]`, `a1[0]`).
"""
from __future__ import annotations

from typing import Any

import yaml

LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
"""libyaml's safe loader where the wheel has it (C, so much faster), PyYAML's own otherwise."""


class UntrustedYamlError(ValueError):
    """Text refused as YAML; the message starts with the field, callers prefix the file."""


def load(text: str, max_depth: int) -> Any:
    """The document, after checking it has no aliases and no nesting deeper than `max_depth`."""
    check_shape(text, max_depth)
    try:
        return yaml.load(text, Loader=LOADER)
    except yaml.YAMLError as error:
        raise UntrustedYamlError(f'not valid YAML: {cut(" ".join(str(error).split()), 200)}') from None
    except (ValueError, RecursionError, OverflowError) as error:  # e.g. an integer beyond Python's digit limit
        raise UntrustedYamlError(f'not valid YAML: {cut(str(error), 200)}') from None


def check_shape(text: str, max_depth: int) -> None:
    """Refuse aliases and collections nested deeper than `max_depth`, naming the field where they appear."""
    path: list[list[Any]] = []   # one [is_mapping, key or index, expecting_a_key] per open collection

    def where() -> str:
        text = ''.join(f'.{key}' if is_map else f'[{key}]' for is_map, key, _ in path).lstrip('.')
        return text or '<top level>'

    def value_done() -> None:
        if path:
            if path[-1][0]:
                path[-1][2] = True
            else:
                path[-1][1] += 1

    try:
        for event in yaml.parse(text, Loader=LOADER):
            if isinstance(event, (yaml.StreamStartEvent, yaml.StreamEndEvent, yaml.DocumentStartEvent,
                                  yaml.DocumentEndEvent)):
                continue
            if path and path[-1][0] and path[-1][2] and not isinstance(event, yaml.CollectionEndEvent):
                path[-1][2] = False   # this node is a key
                path[-1][1] = cut(str(event.value), 40) if isinstance(event, yaml.ScalarEvent) else '?'
                if isinstance(event, yaml.ScalarEvent):
                    continue
            if isinstance(event, yaml.AliasEvent):
                raise UntrustedYamlError(f'{where()}: YAML aliases (*{cut(event.anchor, 40)}) are not allowed')
            if isinstance(event, yaml.CollectionStartEvent):
                if len(path) >= max_depth:
                    raise UntrustedYamlError(f'{where()}: nested deeper than {max_depth} levels')
                is_map = isinstance(event, yaml.MappingStartEvent)
                path.append([is_map, None if is_map else 0, is_map])
            elif isinstance(event, yaml.CollectionEndEvent):
                path.pop()
                value_done()
            else:
                value_done()
    except yaml.YAMLError as error:
        if 'maximum nesting depth' in str(error):   # PyYAML >= 6.0.3's scanner stops far deeper than our bound
            raise UntrustedYamlError(f'{where()}: nested deeper than {max_depth} levels') from None
        raise UntrustedYamlError(f'not valid YAML: {cut(" ".join(str(error).split()), 200)}') from None


def cut(text: str, limit: int) -> str:
    """`text` shortened to `limit` characters: an error message never formats a huge value."""
    return text if len(text) <= limit else text[:limit - 3] + '...'
