"""Simulator announcements: the text round-trips, anything else is not one, and the order is the start order."""
import os

from epuck_ros.ros.announcements import announcement, parse_announcement


def test_an_announcement_round_trips_and_names_this_process():
    own = announcement(1_700_000_000_000_000_000, os.getpid())
    assert parse_announcement(own.text()) == own
    assert own.is_process(os.getpid())
    assert not own.is_process(os.getpid() + 1)


def test_text_that_is_not_an_announcement_is_none():
    for text in ('', 'hello', '12 pid x on host', 'x pid 3 on host', '12 pid 3 at host', '12 pid 3 on host extra'):
        assert parse_announcement(text) is None, text


def test_the_earlier_start_orders_first_whatever_the_pid():
    early, late = announcement(100, 9999), announcement(200, 1)
    assert sorted([late, early]) == [early, late]
