"""The daemon's control endpoint: a Unix domain socket only its owner can reach.

Location (first that applies): ``--socket PATH``; ``$MAVREG_SOCKET``;
``$XDG_RUNTIME_DIR/mavreg.sock``; ``/tmp/mavreg-$UID/mavreg.sock`` (directory created
mode 0700). The socket itself is mode 0600.

Protocol: JSON lines. The client sends **one** request line (UTF-8 JSON object, at most
:data:`MAX_REQUEST_BYTES` including the newline) and reads one response line:

- ``{"op": "upload", "name": "barrel_roll.yaml", "yaml": "<file text>"}`` ->
  ``{"ok": true, "verdict": "accepted", "plan": {...}, "detail": "..."}`` or
  ``{"ok": false, "verdict": "rejected", "reason": "<loader or feasibility message>"}``
- ``{"op": "status"}`` -> ``{"ok": true, "status": {...}}``
- ``{"op": "land"}`` -> ``{"ok": true, "detail": "..."}``

A request that is too long, not JSON, not an object, or has an unknown ``op`` or
missing/extra keys gets ``{"ok": false, "verdict": "refused", "reason": ...}``.

Who may ask, and what a client may cost (docs/reliability.md):

- **the daemon's own user only**: besides the socket's mode 0600, the peer's uid is read
  from the kernel (``SO_PEERCRED``, Linux) and any other uid is refused (root included,
  unless the daemon runs as root);
- **a bounded read**: one request line of at most :data:`MAX_REQUEST_BYTES` (a longer
  one, newline or not, is refused as soon as the limit is passed), complete within
  ``read_timeout_s`` of the connection (a client sending a byte a second is cut off);
- **a bounded number of connections**: at most ``max_connections`` at once; one more is
  refused at once, without reading it.

Every request is answered before its connection is closed. A handler that raises (a
daemon bug) yields ``{"ok": false, "error": "<one line>"}``
and its traceback in the daemon's log; a request still in progress when the daemon stops
(e.g. an upload being planned when the flight aborts) yields ``{"ok": false, "error":
"<why the daemon is stopping>; the request was not completed"}``.
"""
from __future__ import annotations

import asyncio
import json
import os
import socket
import stat
import struct
import sys
import traceback
from pathlib import Path
from typing import Awaitable, Callable

from ...errors import UsageError, one_line

__all__ = ["MAX_REQUEST_BYTES", "MAX_CONNECTIONS", "READ_TIMEOUT_S", "default_socket_path",
           "validate_request", "EndpointServer", "request", "RequestError", "peer_uid", "jsonable"]

MAX_REQUEST_BYTES = 256 * 1024
READ_TIMEOUT_S = 10.0
"""A whole request must arrive within this time of the connection."""
WRITE_TIMEOUT_S = 5.0
MAX_CONNECTIONS = 8
"""Connections served at once (each may hold a request of MAX_REQUEST_BYTES)."""

_KEYS = {"upload": {"op", "name", "yaml"}, "status": {"op"}, "land": {"op"}}


class RequestError(ValueError):
    """A request the endpoint refuses (malformed, oversized, unknown)."""


def default_socket_path() -> Path:
    """Where the daemon listens unless told otherwise (see the module docstring)."""
    env = os.environ.get("MAVREG_SOCKET")
    if env:
        return Path(env)
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and Path(runtime).is_dir():
        return Path(runtime) / "mavreg.sock"
    return Path(f"/tmp/mavreg-{os.getuid()}") / "mavreg.sock"


def peer_uid(sock: socket.socket | None) -> int | None:
    """The uid of the process at the other end of a Unix socket (``SO_PEERCRED``), or None
    where the platform cannot tell."""
    opt = getattr(socket, "SO_PEERCRED", None)
    if sock is None or opt is None:
        return None
    creds = sock.getsockopt(socket.SOL_SOCKET, opt, struct.calcsize("3i"))
    _pid, uid, _gid = struct.unpack("3i", creds)
    return uid


def validate_request(line: bytes) -> dict:
    """Decode and check one request line; raises RequestError with a one-line reason."""
    if len(line) > MAX_REQUEST_BYTES:
        raise RequestError(f"request too large ({len(line)} bytes; limit {MAX_REQUEST_BYTES})")
    try:
        req = json.loads(line.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RequestError(f"malformed request: not UTF-8 JSON ({exc.__class__.__name__})") from None
    if not isinstance(req, dict):
        raise RequestError("malformed request: expected a JSON object")
    op = req.get("op")
    if op not in _KEYS:
        raise RequestError(f"unknown op {op!r}; expected one of {sorted(_KEYS)}")
    if set(req) != _KEYS[op]:
        raise RequestError(f"op {op!r} takes keys {sorted(_KEYS[op])}, got {sorted(req)}")
    if op == "upload" and not (isinstance(req["name"], str) and isinstance(req["yaml"], str)):
        raise RequestError("upload: 'name' and 'yaml' must be strings")
    return req


class EndpointServer:
    """Serves requests on a Unix socket; ``handler(request) -> response`` does the work.

    Every connection that sends a request gets exactly one response line before it is
    closed: the handler's, a refusal (:class:`RequestError`), ``{"ok": false, "error":
    ...}`` when the handler raised anything else (the traceback goes to ``log``), or
    ``{"ok": false, "error": "<close reason>; ..."}`` when :meth:`close` interrupted it.

    Parameters
    ----------
    path : str or Path
        Socket path.
    handler : async callable
        ``handler(request: dict) -> dict`` (a JSON-ready response).
    log : callable, optional
        ``log(text)`` for handler failures (default: stderr).
    read_timeout_s : float, optional
        A request must be complete this long after the connection.
    max_connections : int, optional
        Connections served at once; more are refused without being read.
    """

    def __init__(self, path: str | Path, handler: Callable[[dict], Awaitable[dict]],
                 log: Callable[[str], None] | None = None, read_timeout_s: float = READ_TIMEOUT_S,
                 max_connections: int = MAX_CONNECTIONS):
        self.path = Path(path)
        self.handler = handler
        self.log = log if log is not None else (lambda text: print(text, file=sys.stderr, flush=True))
        self.read_timeout_s = read_timeout_s
        self.max_connections = max_connections
        self.uid = os.geteuid()
        self._server: asyncio.AbstractServer | None = None
        self._clients: set[asyncio.Task] = set()
        self._closing: str | None = None
        self.refused = 0
        """Requests refused: malformed, too large, too slow, another user, too many."""
        self.errors = 0
        """Requests whose handler raised (each answered with an error reply)."""

    @property
    def connections(self) -> int:
        """Clients connected now and being answered (at most ``max_connections``)."""
        return len(self._clients)

    async def start(self) -> None:
        self.path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        if self.path.exists() or self.path.is_symlink():
            if not stat.S_ISSOCK(self.path.lstat().st_mode):
                raise UsageError(f"control socket {self.path} exists and is not a socket")
            if _someone_listening(self.path):
                raise UsageError(f"another daemon is serving on {self.path}")
            self.path.unlink()
        old = os.umask(0o177)
        try:
            self._server = await asyncio.start_unix_server(self._client, path=str(self.path),
                                                           limit=MAX_REQUEST_BYTES + 1)
        finally:
            os.umask(old)
        os.chmod(self.path, 0o600)

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if len(self._clients) >= self.max_connections:
            self.refused += 1
            await self._answer(writer, {"ok": False, "verdict": "refused", "reason":
                                        f"too many connections (at most {self.max_connections} at once)"})
            return
        self._clients.add(task)
        try:
            try:
                line = await self._respond(reader, writer)
            except asyncio.CancelledError:
                # Only close() cancels a client (or the loop's teardown): answer anyway.
                if hasattr(task, "uncancel"):   # Python >= 3.11
                    task.uncancel()
                line = _dump({"ok": False, "error": f"{self._closing or 'the daemon is stopping'}; "
                                                    "the request was not completed"})
            await self._write(writer, line)
        finally:
            self._clients.discard(task)

    async def _answer(self, writer: asyncio.StreamWriter, resp: dict) -> None:
        await self._write(writer, _dump(resp))

    @staticmethod
    async def _write(writer: asyncio.StreamWriter, line: bytes) -> None:
        """Send one line and close; a client that left or does not read costs nothing."""
        try:
            writer.write(line)
            await asyncio.wait_for(writer.drain(), WRITE_TIMEOUT_S)
        except (ConnectionError, OSError, asyncio.TimeoutError, asyncio.CancelledError):
            pass   # the client left, does not read, or the daemon is going away
        finally:
            writer.close()

    def _check_peer(self, writer: asyncio.StreamWriter) -> None:
        try:
            uid = peer_uid(writer.get_extra_info("socket"))
        except OSError as exc:
            raise RequestError(f"cannot tell who is asking ({exc.strerror or exc}); refused") from None
        if uid is not None and uid != self.uid:
            raise RequestError(f"permission denied: uid {uid} is not the daemon's user (uid {self.uid})")

    async def _respond(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> bytes:
        """Read one request and return the response line (never raises but CancelledError)."""
        op = "?"
        try:
            self._check_peer(writer)
            req = await _read_request(reader, self.read_timeout_s)
            op = req["op"]
            return _dump(await self.handler(req))
        except RequestError as exc:
            self.refused += 1
            return _dump({"ok": False, "verdict": "refused", "reason": one_line(exc)})
        except Exception as exc:   # a bug or a failure of the daemon: reply, and log it for developers
            self.errors += 1
            self.log(f"endpoint: {op!r} request failed:\n{traceback.format_exc().rstrip()}")
            return _dump({"ok": False, "error": f"internal error while handling {op!r}: "
                                                f"{exc.__class__.__name__}: {one_line(exc, 300)}"})

    async def close(self, reason: str = "the daemon is stopping") -> None:
        """Stop accepting, answer requests in progress with ``reason``, remove the socket."""
        self._closing = reason
        if self._server is not None:
            self._server.close()
            self._server = None
        clients = [t for t in self._clients if t is not asyncio.current_task()]
        for task in clients:
            task.cancel()
        await asyncio.gather(*clients, return_exceptions=True)
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass


async def _read_request(reader: asyncio.StreamReader, timeout_s: float = READ_TIMEOUT_S) -> dict:
    try:
        line = await asyncio.wait_for(reader.readuntil(b"\n"), timeout_s)
    except asyncio.LimitOverrunError:
        raise RequestError(f"request too large (limit {MAX_REQUEST_BYTES} bytes)") from None
    except asyncio.IncompleteReadError as exc:
        if len(exc.partial) > MAX_REQUEST_BYTES:
            raise RequestError(f"request too large (limit {MAX_REQUEST_BYTES} bytes)") from None
        raise RequestError("malformed request: no newline-terminated line") from None
    except asyncio.TimeoutError:
        raise RequestError(f"no complete request within {timeout_s:g} s") from None
    except (ConnectionError, OSError) as exc:   # the client went away: nobody to answer, not a bug
        raise RequestError(f"connection lost before a complete request ({exc.__class__.__name__})") from None
    return validate_request(line)


def jsonable(obj):
    """``obj`` with numpy scalars and arrays made plain (a plan's summary holds them)."""
    import numpy as np
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _dump(resp: dict) -> bytes:
    """One JSON line; a response that does not serialize raises TypeError/ValueError."""
    return (json.dumps(resp) + "\n").encode()


def _someone_listening(path: Path) -> bool:
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        s.connect(str(path))
        return True
    except OSError:
        return False
    finally:
        s.close()


def request(path: str | Path, req: dict, timeout_s: float = 120.0) -> dict:
    """Blocking client: send one request, return the response (for ``mavreg upload``).

    Raises OSError when nothing listens at ``path``.
    """
    data = (json.dumps(req) + "\n").encode()
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(timeout_s)
        s.connect(str(path))
        try:
            s.sendall(data)
        except (BrokenPipeError, ConnectionResetError):
            pass   # refused before it was read (too many connections, another user): the reply waits
        buf = bytearray()
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
    if not buf:
        raise OSError(f"no response from {path}")
    return json.loads(buf.decode())
