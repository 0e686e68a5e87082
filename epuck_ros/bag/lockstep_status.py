"""Whether a recorded run is reproducible: the last `lockstep_status` the simulator published (latched, so a
recorder that joined late has it too), read from a bag without ROS."""
from __future__ import annotations

from epuck_ros.bag.cdr import CdrDecoder, CdrError
from epuck_ros.bag.reader import Bag
from epuck_ros.integrity import STATUS_TOPIC, STATUS_TYPE, Integrity, integrity_from


def recorded_integrity(bag: Bag) -> Integrity | None:
    """The run's verdict as the bag holds it; None when it holds none (a bag of an older simulator, or of topics
    chosen without it) or an undecodable one."""
    topic = next((t for t in bag.topics.values()
                  if t.name.rsplit('/', 1)[-1] == STATUS_TOPIC and t.type_name == STATUS_TYPE), None)
    if topic is None:
        return None
    last = None
    for _, _, _, buffer, start, end in bag.iter_raw([topic.name]):
        last = bytes(buffer[start:end])
    if last is None:
        return None
    try:
        status = CdrDecoder(topic.type_name, topic.schema_text).decode(last)
    except CdrError:
        return None
    return integrity_from(status['message'], {value['key']: value['value'] for value in status['values']})
