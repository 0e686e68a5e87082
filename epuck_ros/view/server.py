"""The view's web server, without ROS: the page and its assets, a live event stream, and a few fixed actions.

Standard library only (`http.server.ThreadingHTTPServer`): the page needs one stream from the server (Server-Sent
Events, which every browser's `EventSource` reads) and a handful of small POSTs, so a web framework or a
websocket library would add a dependency and nothing the page uses.

- `GET /` the page, `GET /static/<file>` its assets (only the files shipped in `view/static`).
- `GET /events?robot=NAME` Server-Sent Events: `world` on connect and whenever the world changes, `state` at most
  `MAX_FRAME_RATE` times a second and only when something changed. NAME is the robot the page shows in detail.
  The view reads only while a page is open (`ViewServer.pages_open`), and a robot's own topics only for the
  robots a page shows in detail (`ViewServer.watched`; `view.follow`): each subscriber costs the simulator a send
  per step.
- `GET /state?robot=NAME`, `GET /world` the same JSON once (for scripts and benchmarks); `GET /camera?robot=NAME`
  the newest camera image of the robot shown in detail (PNG; 404 before the first).
- `POST /api/<action>` with a JSON body: one of ACTIONS, checked by `parse_action` before anything reaches ROS.

A POST must be `application/json` and, if the browser says where it comes from (`Origin`), come from this very
page: another web site open in the same browser cannot drive the robot. Served on loopback, the `Host` must be a
loopback name too (a DNS-rebinding page cannot either).
"""
from __future__ import annotations

import json
import math
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from urllib.parse import parse_qs, urlsplit

from epuck_ros.loopback import is_loopback
from epuck_ros.view.state import ViewState

MAX_FRAME_RATE = 30.0
"""State events per second at most, whatever the simulator's rate: more than a screen shows is wasted."""
POLL_LEASE = 5.0
"""Wall seconds a `GET /state[?robot=NAME]` counts as an open page (showing NAME in detail)."""
MAX_BODY = 4096
"""Bytes; every action fits in far less."""
MAX_LINEAR_SPEED = 0.5
"""m/s accepted from the page (the e-puck's wheels clamp at 6.28 rad/s x 0.02 m = 0.126 m/s anyway)."""
MAX_ANGULAR_SPEED = 10.0
"""rad/s accepted from the page (the e-puck clamps at 2 x 0.126 / 0.052 = 4.8 rad/s)."""

CONTENT_TYPES = {'.html': 'text/html; charset=utf-8', '.js': 'text/javascript; charset=utf-8',
                 '.css': 'text/css; charset=utf-8', '.png': 'image/png', '.svg': 'image/svg+xml'}
LOOPBACK_NAMES = {'localhost', '127.0.0.1', '::1'}
MAX_STREAMS = 16
"""Event streams open at once at most (each a thread sending up to 30 frames a second: hundreds of them took the
cores from the simulator); one more is answered 503."""
MAX_POLLED = 64
"""Robot names remembered from GET /state at most (each distinct name was kept for ever: a client making names up
grew the view's memory without bound)."""
IDLE_TIMEOUT = 10.0
"""Wall seconds a connection may stay silent (no request, or a request's body not coming) before it is closed."""
LISTEN_BACKLOG = 64
"""Connections waiting to be accepted (http.server's default is 5)."""


class ActionError(ValueError):
    """A request the view refuses; the message says why (sent back with status 400)."""


@dataclass(frozen=True)
class Action:
    """A validated request from the page: `name` is one of ACTIONS, `args` its checked arguments."""

    name: str
    args: dict


def _number(body: dict, key: str, low: float, high: float) -> float:
    value = body.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ActionError(f'{key}: expected a finite number, got {value!r}')
    if not low <= value <= high:
        raise ActionError(f'{key}: {value} is outside [{low:g}, {high:g}]')
    return float(value)


def _no_arguments(body: dict) -> dict:
    if body:
        raise ActionError(f'unexpected arguments {sorted(body)}')
    return {}


def _pause(body: dict) -> dict:
    if set(body) != {'paused'} or not isinstance(body['paused'], bool):
        raise ActionError('expected {"paused": true|false}')
    return {'paused': body['paused']}


def _real_time_factor(body: dict) -> dict:
    if set(body) != {'value'}:
        raise ActionError('expected {"value": real-time factor}')
    return {'value': _number(body, 'value', 0.0, math.inf)}  # the simulator's parameter range does the rest


def _drive(body: dict) -> dict:
    if set(body) != {'robot', 'linear', 'angular'} or not isinstance(body['robot'], str):
        raise ActionError('expected {"robot": name, "linear": m/s, "angular": rad/s}')
    return {'robot': body['robot'], 'linear': _number(body, 'linear', -MAX_LINEAR_SPEED, MAX_LINEAR_SPEED),
            'angular': _number(body, 'angular', -MAX_ANGULAR_SPEED, MAX_ANGULAR_SPEED)}


ACTIONS: dict[str, Callable[[dict], dict]] = {
    'pause': _pause,            # set the simulator's `paused` parameter
    'step': _no_arguments,      # call its `step` service (one step while paused)
    'reset': _no_arguments,     # call its `reset` service
    'real_time_factor': _real_time_factor,  # set its `real_time_factor` parameter
    'drive': _drive,            # publish a Twist on the robot's cmd_vel
}
"""The only things the page can ask for, each with the function that checks its arguments."""


def parse_action(path: str, body: bytes) -> Action:
    """The Action a POST asks for, or ActionError: unknown path, not a JSON object, or arguments out of range."""
    prefix = '/api/'
    name = path[len(prefix):] if path.startswith(prefix) else ''
    if name not in ACTIONS:
        raise ActionError(f'unknown action {path!r} (known: {", ".join(prefix + a for a in ACTIONS)})')
    try:
        decoded = json.loads(body.decode('utf-8')) if body.strip() else {}
    except (UnicodeDecodeError, ValueError) as error:   # JSONDecodeError, or an integer of over 4,300 digits
        raise ActionError(f'body is not JSON: {str(error)[:200]}') from None
    except RecursionError:
        raise ActionError('body is not JSON this page sends: nested too deep') from None
    if not isinstance(decoded, dict):
        raise ActionError('body must be a JSON object')
    try:
        return Action(name, ACTIONS[name](decoded))
    except (OverflowError, ValueError, TypeError) as error:   # e.g. a 400-digit integer as a speed
        raise ActionError(f'{name}: bad argument: {str(error)[:200]}') from None


ActionHandler = Callable[[Action], dict]
"""Carries out an Action (the view node); returns what the page is told; raises ActionError to refuse."""


def static_file(name: str) -> bytes | None:
    """The content of a shipped asset, or None: only the names in the package's static folder are served."""
    folder = resources.files('epuck_ros.view') / 'static'
    if '/' in name or name.startswith('.') or not (folder / name).is_file():
        return None
    return (folder / name).read_bytes()


class ViewServer(ThreadingHTTPServer):
    """The HTTP server: `serve_forever()` in a thread, `close()` to stop it and every open event stream."""

    daemon_threads = True
    request_queue_size = LISTEN_BACKLOG

    def __init__(self, host: str, port: int, state: ViewState, act: ActionHandler) -> None:
        self.state, self.act = state, act
        self.stopping = threading.Event()
        self._watch_lock = threading.Lock()
        self._streams: dict[int, str] = {}  # open event stream -> the robot it shows in detail
        self._polls: dict[str, float] = {}  # robot -> wall time of the last GET /state for it
        self.loopback_only = is_loopback(host)
        if ':' in host:
            self.address_family = socket.AF_INET6
        super().__init__((host, port), _Handler)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f'http://[{host}]:{port}/' if ':' in host else f'http://{host}:{port}/'

    def _looking(self) -> set[str]:
        """What the open streams and recent polls show in detail ('' for none)."""
        now = time.monotonic()
        with self._watch_lock:
            return set(self._streams.values()) | {robot for robot, at in self._polls.items() if now - at < POLL_LEASE}

    def pages_open(self) -> bool:
        """Whether any page (an event stream, or a poll within POLL_LEASE) is looking at the view."""
        return bool(self._looking())

    def watched(self) -> set[str]:
        """The robots some page shows in detail now."""
        return self._looking() - {''}

    def watch_stream(self, stream: int, robot: str) -> bool:
        """Note an event stream showing `robot`; False when MAX_STREAMS are open already."""
        with self._watch_lock:
            if len(self._streams) >= MAX_STREAMS:
                return False
            self._streams[stream] = robot
            return True

    def end_stream(self, stream: int) -> None:
        with self._watch_lock:
            self._streams.pop(stream, None)

    def note_poll(self, robot: str) -> None:
        """Remember that a page polls `robot`: only robots the world has (once known), at most MAX_POLLED, expired
        ones dropped."""
        known = self.state.robot_names
        if robot and known and robot not in known:
            return
        now = time.monotonic()
        with self._watch_lock:
            self._polls = {name: at for name, at in self._polls.items() if now - at < POLL_LEASE}
            if robot in self._polls or len(self._polls) < MAX_POLLED:
                self._polls[robot] = now

    def close(self) -> None:
        self.stopping.set()
        self.shutdown()
        self.server_close()


class _Handler(BaseHTTPRequestHandler):
    server: ViewServer
    protocol_version = 'HTTP/1.1'
    timeout = IDLE_TIMEOUT   # the socket's: an idle or half-sent connection does not hold its thread for ever

    def parse_request(self) -> bool:
        """http.server's parsing, then the Host check for every request (GET too: a DNS-rebinding page could read
        /state, /world and /events)."""
        if not super().parse_request():
            return False
        refusal = self._foreign_host()
        if refusal:
            self.close_connection = True
            self._send_error(HTTPStatus.FORBIDDEN, refusal)
            return False
        return True

    def _foreign_host(self) -> str:
        """Why this request's Host is not this server on loopback, or ''."""
        host = self.headers.get('Host', '')
        if self.server.loopback_only and urlsplit(f'//{host}').hostname not in LOOPBACK_NAMES:
            return f'Host {host!r} is not this machine'
        return ''

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - the base class's name
        """Quiet: a page polling or streaming would fill the terminal."""

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        url = urlsplit(self.path)
        path, robot = url.path, parse_qs(url.query).get('robot', [''])[0]
        if path in ('/', '/index.html'):
            self._send_static('index.html')
        elif path.startswith('/static/'):
            self._send_static(path[len('/static/'):])
        elif path == '/events':
            self._stream_events(robot)
        elif path == '/state':
            self.server.note_poll(robot)
            self._send(HTTPStatus.OK, self.server.state.frame_json(time.monotonic()).encode(), 'application/json')
        elif path == '/camera':
            png = self.server.state.camera_png(robot)
            if png is None:
                self._send_error(HTTPStatus.NOT_FOUND, 'no camera image of that robot (yet)')
            else:
                self._send(HTTPStatus.OK, png, 'image/png')
        elif path == '/world':
            self._send(HTTPStatus.OK, self.server.state.world_json().encode(), 'application/json')
        else:
            self._send_error(HTTPStatus.NOT_FOUND, f'no such page: {path}')

    def do_POST(self) -> None:  # noqa: N802
        refusal = self._refuse_post()
        if refusal:
            self._send_error(HTTPStatus.FORBIDDEN, refusal)
            return
        length = self.headers.get('Content-Length', '')
        if not length.isdigit() or len(length) > 9 or int(length) > MAX_BODY:
            self._send_error(HTTPStatus.BAD_REQUEST, f'a body of at most {MAX_BODY} bytes with Content-Length')
            return
        try:
            action = parse_action(urlsplit(self.path).path, self.rfile.read(int(length)))
            result = self.server.act(action)
        except ActionError as error:
            self._send_error(HTTPStatus.BAD_REQUEST, str(error))
            return
        self._send(HTTPStatus.OK, json.dumps(result).encode(), 'application/json')

    def _refuse_post(self) -> str:
        """Why this POST may not act, or '' (see the module docstring)."""
        if self.headers.get('Content-Type', '').split(';')[0].strip() != 'application/json':
            return 'actions must be sent as application/json'
        host = self.headers.get('Host', '')
        origin = self.headers.get('Origin')
        if origin is not None and urlsplit(origin).netloc != host:
            return f'Origin {origin!r} is not this page'
        return ''

    def _send(self, status: HTTPStatus, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header('Content-Type', content_type)
        self.send_header('Content-Length', str(len(body)))
        self.send_header('Cache-Control', 'no-store')
        self.end_headers()
        self.wfile.write(body)

    def _send_error(self, status: HTTPStatus, message: str) -> None:
        self._send(status, json.dumps({'error': message}).encode(), 'application/json')

    def _send_static(self, name: str) -> None:
        content = static_file(name)
        if content is None:
            self._send_error(HTTPStatus.NOT_FOUND, f'no such file: {name}')
            return
        suffix = name[name.rfind('.'):]
        self._send(HTTPStatus.OK, content, CONTENT_TYPES.get(suffix, 'application/octet-stream'))

    def _stream_events(self, robot: str) -> None:
        """Send `world` and `state` events until the client goes away or the server stops."""
        state, stopping = self.server.state, self.server.stopping
        if not self.server.watch_stream(id(self), robot):
            self.close_connection = True
            self._send_error(HTTPStatus.SERVICE_UNAVAILABLE, f'{MAX_STREAMS} pages are open already')
            return
        self.send_response(HTTPStatus.OK)
        self.send_header('Content-Type', 'text/event-stream')
        self.send_header('Cache-Control', 'no-store')
        self.end_headers()
        self.close_connection = True
        sent_world, sent_version, last_write = -1, -1, time.monotonic()
        try:
            while not stopping.is_set():
                version = state.wait_for_change(sent_version, timeout=1.0)
                now = time.monotonic()
                if state.world_version != sent_world:
                    sent_world = state.world_version
                    self._event('world', state.world_json())
                    last_write = now
                # The real-time factor reached decays while time stands still, so a frame is also due each second
                # (which keeps an idle stream open, too).
                if version != sent_version or now - last_write >= 1.0:
                    sent_version = version
                    self._event('state', state.frame_json(now))
                    last_write = now
                stopping.wait(1.0 / MAX_FRAME_RATE)
        except (BrokenPipeError, ConnectionResetError, TimeoutError):
            pass  # the page was closed, or stopped reading
        finally:
            self.server.end_stream(id(self))

    def _event(self, kind: str, data: str) -> None:
        self.wfile.write(f'event: {kind}\ndata: {data}\n\n'.encode())
        self.wfile.flush()
