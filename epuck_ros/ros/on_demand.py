"""A swarm's per-robot topics, made only once someone uses them (from TOPICS_ON_DEMAND_FROM robots).

A publisher (odom, ir_raw, collisions, robot_description, ...) is made once a reader of its topic is in the graph, a
subscription (wheel_cmd, cmd_vel) once a writer is: a user's node, `ros2 topic echo`, the view, Foxglove or a recorder
that names a robot's topic gets it, with the step protocol, as below that size. A robot nobody reads or drives by its
own topics costs nothing: a 2,000-robot simulator's start-up and memory went mostly to its 18,000 endpoints, and
every look at the graph grew with them, while a swarm controller reads and drives all its robots through the swarm
topics (`swarm_ports`). The price: a topic nobody uses is not in the graph (`ros2 topic list` does not show it), so
a reader names it with its type, and it is made within one look (SENSE_POLL) of its first reader or writer.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable

TOPICS_ON_DEMAND_FROM = 200
"""Robots from which a robot's topics are made on demand: below, they cost little at start and all are listed."""


class OnDemand:
    """The topics waiting for their first reader or writer, by full name, and what makes each."""

    def __init__(self) -> None:
        self._waiting: dict[str, tuple[bool, Callable[[], None]]] = {}

    def add(self, topic: str, make: Callable[[], None], by_writer: bool = False) -> None:
        """`make` runs once `topic` (a full name) has a reader, or with `by_writer` a writer."""
        self._waiting[topic] = (by_writer, make)

    def __len__(self) -> int:
        return len(self._waiting)

    def due(self, graph: Iterable[str], readers: Callable[[str], int], writers: Callable[[str], int]
            ) -> list[Callable[[], None]]:
        """The makers of the waiting topics among `graph` (the graph's topic names: one look for all, a topic with
        only a reader or a writer is in it) that now have their reader or writer; they wait no longer. Only the
        graph's topics are looked at, which are those in use: the look grows with them, not with the robots."""
        due = []
        for topic in graph:
            waiting = self._waiting.get(topic)
            if waiting is not None and (writers if waiting[0] else readers)(topic):
                del self._waiting[topic]
                due.append(waiting[1])
        return due
