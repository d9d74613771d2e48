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

Every request is answered before its connection is closed. A handler that raises (a
daemon bug, or the planner worker dying) yields ``{"ok": false, "error": "<one line>"}``
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
import sys
import traceback
from pathlib import Path
from typing import Awaitable, Callable

__all__ = ["MAX_REQUEST_BYTES", "default_socket_path", "validate_request", "EndpointServer",
           "request", "RequestError"]

MAX_REQUEST_BYTES = 256 * 1024
READ_TIMEOUT_S = 10.0
WRITE_TIMEOUT_S = 5.0

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
    """

    def __init__(self, path: str | Path, handler: Callable[[dict], Awaitable[dict]],
                 log: Callable[[str], None] | None = None):
        self.path = Path(path)
        self.handler = handler
        self.log = log if log is not None else (lambda text: print(text, file=sys.stderr, flush=True))
        self._server: asyncio.AbstractServer | None = None
        self._clients: set[asyncio.Task] = set()
        self._closing: str | None = None
        self.refused = 0
        self.errors = 0
        """Requests whose handler raised (each answered with an error reply)."""

    async def start(self) -> None:
        self.path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        if self.path.exists() or self.path.is_symlink():
            if not stat.S_ISSOCK(self.path.lstat().st_mode):
                raise ValueError(f"control socket {self.path} exists and is not a socket")
            if _someone_listening(self.path):
                raise ValueError(f"another daemon is serving on {self.path}")
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
        self._clients.add(task)
        try:
            try:
                line = await self._respond(reader)
            except asyncio.CancelledError:
                # Only close() cancels a client (or the loop's teardown): answer anyway.
                if hasattr(task, "uncancel"):   # Python >= 3.11
                    task.uncancel()
                line = _dump({"ok": False, "error": f"{self._closing or 'the daemon is stopping'}; "
                                                    "the request was not completed"})
            try:
                writer.write(line)
                await asyncio.wait_for(writer.drain(), WRITE_TIMEOUT_S)
            except (ConnectionError, OSError, asyncio.TimeoutError, asyncio.CancelledError):
                pass   # the client left, does not read, or the daemon is going away
        finally:
            self._clients.discard(task)
            writer.close()

    async def _respond(self, reader: asyncio.StreamReader) -> bytes:
        """Read one request and return the response line (never raises but CancelledError)."""
        op = "?"
        try:
            req = await _read_request(reader)
            op = req["op"]
            return _dump(await self.handler(req))
        except RequestError as exc:
            self.refused += 1
            return _dump({"ok": False, "verdict": "refused", "reason": str(exc)})
        except Exception as exc:   # a bug or a failure of the daemon: reply, and log it for developers
            self.errors += 1
            self.log(f"endpoint: {op!r} request failed:\n{traceback.format_exc().rstrip()}")
            return _dump({"ok": False, "error": f"internal error while handling {op!r}: "
                                                f"{exc.__class__.__name__}: {_one_line(exc)}"})

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


async def _read_request(reader: asyncio.StreamReader) -> dict:
    try:
        line = await asyncio.wait_for(reader.readuntil(b"\n"), READ_TIMEOUT_S)
    except asyncio.LimitOverrunError:
        raise RequestError(f"request too large (limit {MAX_REQUEST_BYTES} bytes)") from None
    except asyncio.IncompleteReadError as exc:
        if len(exc.partial) > MAX_REQUEST_BYTES:
            raise RequestError(f"request too large (limit {MAX_REQUEST_BYTES} bytes)") from None
        raise RequestError("malformed request: no newline-terminated line") from None
    except asyncio.TimeoutError:
        raise RequestError(f"no complete request within {READ_TIMEOUT_S:g} s") from None
    except (ConnectionError, OSError) as exc:   # the client went away: nobody to answer, not a bug
        raise RequestError(f"connection lost before a complete request ({exc.__class__.__name__})") from None
    return validate_request(line)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text[:300] + ("..." if len(text) > 300 else "") if text else "(no message)"


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
        s.sendall(data)
        buf = bytearray()
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
    if not buf:
        raise OSError(f"no response from {path}")
    return json.loads(buf.decode())
