"""How others find and reach the Foxglove bridge (`foxglove`, `bringup --foxglove`): its node's name, the defaults,
and whether an address can be served on, asked before anything starts so that a taken port is one clear line, not a
child that dies later.

No ROS and no Foxglove SDK here: `bringup` reads it while it checks its options.
"""
from __future__ import annotations

import ipaddress
import socket

NODE_NAME = 'foxglove'
"""The bridge's node: `bringup` takes it reading /clock as the server being up."""
DEFAULT_PORT = 8765
"""The Foxglove WebSocket protocol's customary port (the app's "Open connection" suggests ws://localhost:8765)."""
DEFAULT_HOST = '127.0.0.1'
"""Loopback: only this machine sees the run unless the user says otherwise."""
ADVICE = 'another foxglove, view or bringup may be serving there; pick another port'


def address_error(host: str, port: int) -> str | None:
    """Why `host:port` cannot be served on (the end of "cannot serve on HOST:PORT: ..."), or None if it can.
    Bound with SO_REUSEADDR, as the SDK's listener (tokio's) binds: a port whose last connections are still in
    TIME_WAIT is free for both."""
    if not 0 <= port <= 65535:
        return f'port {port} is not between 0 and 65535'
    try:
        family, kind, protocol, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except (socket.gaierror, UnicodeError) as error:
        return f'unknown host ({error})'
    with socket.socket(family, kind, protocol) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(address)
        except OSError as error:
            return f'{error.strerror or error}' + (f' ({ADVICE})' if port else '')
    return None


def websocket_url(host: str, port: int) -> str:
    """What to type in Foxglove's "Open connection": an IPv6 address in brackets (`ws://[::]:8765`, not
    `ws://:::8765`)."""
    try:
        bracketed = f'[{host}]' if ipaddress.ip_address(host).version == 6 else host
    except ValueError:   # a name
        bracketed = host
    return f'ws://{bracketed}:{port}'
