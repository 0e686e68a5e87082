"""Whether an address reaches this machine only: the view and the Foxglove bridge serve on loopback unless told
otherwise, and say so (or refuse what only a local user may do) when they do not."""
from __future__ import annotations

import ipaddress
import socket


def is_loopback(host: str) -> bool:
    """Whether serving on `host` reaches this machine only: every address it resolves to, as the server resolves it,
    is a loopback one (`127.1` is 127.0.0.1, which `ipaddress` refuses to parse; `localhost`, `::1`)."""
    try:
        resolved = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError):
        return False
    return bool(resolved) and all(ipaddress.ip_address(address[0].split('%')[0]).is_loopback
                                  for *_, address in resolved)
