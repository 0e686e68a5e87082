"""``bag csv``: one topic's messages as a table, for a spreadsheet or pandas.

Generic over message types: the bag's own schema drives the decoder. Nested fields get dotted
names (``pose.pose.position.x``), array elements an index (``position[0]``) unless joined into
one cell; Time and Duration fields are one exact ``seconds.nanoseconds`` column.
"""
from __future__ import annotations

import csv
from typing import TextIO

from epuck_ros.bag.cdr import CdrDecoder, TimeValue
from epuck_ros.bag.reader import Bag, BagError


def _cell(value: object) -> object:
    return repr(value) if isinstance(value, float) else value


def export_csv(bag: Bag, topic: str, output: TextIO, join_arrays: bool = False) -> int:
    """Write the topic's messages in log_time order; returns the number of rows."""
    if topic not in bag.topics:
        raise BagError(f'{bag.path}: no topic {topic} (topics: {", ".join(sorted(bag.topics)) or "none"})')
    info = bag.topics[topic]
    if info.schema_encoding != 'ros2msg':
        raise BagError(f'{bag.path}: topic {topic} has a {info.schema_encoding or "missing"} schema; '
                       'only ros2msg can be decoded')
    decoder = CdrDecoder(info.type_name, info.schema_text)
    rows = []
    for _, log_time, publish_time, buffer, start, end in bag.iter_raw([topic]):
        row = {'log_time': TimeValue(log_time), 'publish_time': TimeValue(publish_time)}
        row.update(decoder.flat(buffer, start, end, join_arrays))
        rows.append(row)
    rows.sort(key=lambda r: r['log_time'].nanoseconds)
    columns = list(dict.fromkeys(name for row in rows for name in row)) or ['log_time', 'publish_time']
    writer = csv.DictWriter(output, fieldnames=columns, restval='', lineterminator='\n')
    writer.writeheader()
    for row in rows:
        writer.writerow({name: _cell(value) for name, value in row.items()})
    return len(rows)
