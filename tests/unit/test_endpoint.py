"""Control endpoint: mode 0600, JSON lines, oversized and malformed requests refused."""
import asyncio
import json
import os
import socket
import stat
import time

import pytest

from mavreg.daemon.jobs.endpoint import (MAX_REQUEST_BYTES, EndpointServer, RequestError, default_socket_path,
                                    request, validate_request)
from tests.helpers.waiting import wait_until


def test_default_location(monkeypatch, tmp_path):
    monkeypatch.delenv("MAVREG_SOCKET", raising=False)
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    assert default_socket_path() == tmp_path / "mavreg.sock"
    monkeypatch.delenv("XDG_RUNTIME_DIR")
    assert default_socket_path() == __import__("pathlib").Path(f"/tmp/mavreg-{os.getuid()}/mavreg.sock")
    monkeypatch.setenv("MAVREG_SOCKET", str(tmp_path / "x.sock"))
    assert default_socket_path() == tmp_path / "x.sock"


@pytest.mark.parametrize("line, why", [
    (b"not json\n", "malformed"),
    (b"[1, 2]\n", "object"),
    (b'{"op": "fly"}\n', "unknown op"),
    (b'{"op": "upload", "name": "a"}\n', "takes keys"),
    (b'{"op": "status", "extra": 1}\n', "takes keys"),
    (b'{"op": "upload", "name": 3, "yaml": "x"}\n', "strings"),
    (b"\xff\xfe\n", "UTF-8"),
])
def test_validate_refuses(line, why):
    with pytest.raises(RequestError, match=why):
        validate_request(line)


def test_validate_accepts():
    assert validate_request(b'{"op": "upload", "name": "a.yaml", "yaml": "kind: maneuver"}\n')["op"] == "upload"


def _serve(tmp_path, fn):
    path = tmp_path / "s" / "mavreg.sock"
    seen = []

    async def handler(req):
        seen.append(req)
        return {"ok": True, "echo": req["op"]}

    async def main():
        server = EndpointServer(path, handler)
        await server.start()
        try:
            return await asyncio.get_running_loop().run_in_executor(None, fn, path), server.refused
        finally:
            await server.close()
    result, refused = asyncio.run(main())
    return path, seen, result, refused


def test_socket_mode_and_round_trip(tmp_path):
    def client(path):
        mode = stat.S_IMODE(os.stat(path).st_mode)
        return mode, request(path, {"op": "status"}, 10)
    path, seen, (mode, resp), refused = _serve(tmp_path, client)
    assert mode == 0o600
    assert stat.S_IMODE(os.stat(path.parent).st_mode) == 0o700
    assert resp == {"ok": True, "echo": "status"} and seen == [{"op": "status"}]
    assert not path.exists()   # removed on close


def _raw(path, data: bytes) -> dict:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(10)
        s.connect(str(path))
        try:
            s.sendall(data)
        except BrokenPipeError:
            pass
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
    return json.loads(buf)


def test_oversized_and_malformed_requests_refused(tmp_path):
    def client(path):
        big = json.dumps({"op": "upload", "name": "x", "yaml": "a" * (MAX_REQUEST_BYTES + 10)}).encode() + b"\n"
        return [_raw(path, big), _raw(path, b"{nope\n"), _raw(path, b'{"op": "status"}\n')]
    _, seen, (r_big, r_bad, r_ok), refused = _serve(tmp_path, client)
    assert r_big["verdict"] == "refused" and "too large" in r_big["reason"]
    assert r_bad["verdict"] == "refused" and "malformed" in r_bad["reason"]
    assert r_ok["ok"] and seen == [{"op": "status"}] and refused == 2


def test_refuses_to_replace_a_live_socket_or_a_file(tmp_path):
    path = tmp_path / "mavreg.sock"
    path.write_text("not a socket")

    async def main():
        with pytest.raises(ValueError, match="not a socket"):
            await EndpointServer(path, None).start()
    asyncio.run(main())


def _serve_with(tmp_path, handler, client_fn):
    """Run ``client_fn(path)`` in a thread against a server with ``handler``; returns (result, server, log)."""
    path = tmp_path / "s" / "mavreg.sock"
    log: list[str] = []

    async def main():
        server = EndpointServer(path, handler, log.append)
        await server.start()
        try:
            return await asyncio.get_running_loop().run_in_executor(None, client_fn, path), server
        finally:
            await server.close()
    result, server = asyncio.run(main())
    return result, server, log


def test_handler_exception_gets_an_error_reply_and_the_server_keeps_serving(tmp_path):
    async def handler(req):
        if req["op"] == "land":
            raise KeyError("no such thing\nsecond line")
        if req["op"] == "upload":
            return {"ok": True, "not json": object()}   # a response that does not serialize
        return {"ok": True, "echo": req["op"]}

    def client(path):
        return [request(path, {"op": "land"}, 10), request(path, {"op": "upload", "name": "a", "yaml": ""}, 10),
                request(path, {"op": "status"}, 10)]
    (r_land, r_upload, r_status), server, log = _serve_with(tmp_path, handler, client)
    assert r_land["ok"] is False and "KeyError" in r_land["error"] and "\n" not in r_land["error"]
    assert "'land'" in r_land["error"]
    assert r_upload["ok"] is False and "TypeError" in r_upload["error"]
    assert r_status == {"ok": True, "echo": "status"}
    assert server.errors == 2 and server.refused == 0
    # developers get the tracebacks
    assert len(log) == 2 and all("Traceback (most recent call last)" in t for t in log)
    assert "KeyError" in log[0] and "TypeError" in log[1]


def test_request_in_progress_when_the_server_closes_gets_the_reason(tmp_path):
    path = tmp_path / "s" / "mavreg.sock"
    started = asyncio.Event()

    async def handler(req):
        started.set()
        await asyncio.Event().wait()   # an upload being planned, until the server closes
        return {"ok": True}

    async def main():
        server = EndpointServer(path, handler, lambda text: None)
        await server.start()
        loop = asyncio.get_running_loop()
        pending = loop.run_in_executor(None, request, path, {"op": "upload", "name": "a", "yaml": ""}, 30)
        await asyncio.wait_for(started.wait(), 10)
        await server.close("the daemon is stopping (phase aborted; stale state)")
        return await pending
    resp = asyncio.run(main())
    assert resp == {"ok": False, "error": "the daemon is stopping (phase aborted; stale state); "
                                          "the request was not completed"}
    assert not path.exists()


# ---------------------------------------------------------------- hostile clients (issue 21)
def _serve_hostile(tmp_path, client_fn, **server_kwargs):
    """``client_fn(path, server)`` in a thread against a server answering status; returns
    (result, server)."""
    async def handler(req):
        return {"ok": True, "echo": req["op"]}
    path = tmp_path / "s" / "mavreg.sock"

    async def main():
        server = EndpointServer(path, handler, lambda text: None, **server_kwargs)
        await server.start()
        try:
            return await asyncio.get_running_loop().run_in_executor(None, client_fn, path, server), server
        finally:
            await server.close()
    return asyncio.run(main())


def _read_line(s: socket.socket) -> dict:
    buf = b""
    while not buf.endswith(b"\n"):
        chunk = s.recv(65536)
        if not chunk:
            break
        buf += chunk
    return json.loads(buf)


def test_an_over_long_line_without_newline_is_refused_at_the_limit(tmp_path):
    """The client keeps its connection open and never sends a newline: the refusal comes as
    the limit is passed, not at the read timeout (60 s here)."""
    def client(path, _server):
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.settimeout(30)
            s.connect(str(path))
            sent = 0
            try:
                while sent <= MAX_REQUEST_BYTES + 65536:
                    s.sendall(b"a" * 65536)
                    sent += 65536
            except (BrokenPipeError, ConnectionResetError):
                pass
            return _read_line(s)
    resp, server = _serve_hostile(tmp_path, client, read_timeout_s=60.0)
    assert resp["verdict"] == "refused" and "too large" in resp["reason"] and server.refused == 1


def test_a_slow_client_is_cut_off_at_the_read_timeout(tmp_path):
    """A byte every 0.1 s (slow loris) never completes a request within the 1 s allowed."""
    def client(path, _server):
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.settimeout(30)
            s.connect(str(path))
            sent = 0
            try:
                for byte in b'{"op": "status"}' * 100:
                    s.sendall(bytes([byte]))
                    sent += 1
                    time.sleep(0.1)
            except (BrokenPipeError, ConnectionResetError):
                pass
            return sent, _read_line(s)
    (sent, resp), server = _serve_hostile(tmp_path, client, read_timeout_s=1.0)
    assert resp["verdict"] == "refused" and "no complete request within 1 s" in resp["reason"]
    assert sent < 1600 and server.refused == 1


def test_connections_beyond_the_cap_are_refused_and_the_cap_frees_up(tmp_path):
    def client(path, server):
        idle = []
        for _ in range(2):                       # two clients that send nothing
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.settimeout(30)
            s.connect(str(path))
            idle.append(s)
        wait_until(lambda: server.connections == 2, "both idle clients accepted", 30)
        third = request(path, {"op": "status"}, 10)
        replies = [_read_line(s) for s in idle]  # each cut off at the read timeout
        for s in idle:
            s.close()
        return third, replies, request(path, {"op": "status"}, 10)
    (third, replies, later), server = _serve_hostile(tmp_path, client, read_timeout_s=1.0, max_connections=2)
    assert third["verdict"] == "refused" and "too many connections (at most 2" in third["reason"]
    assert all("no complete request" in r["reason"] for r in replies)
    assert later == {"ok": True, "echo": "status"} and server.refused == 3


def test_another_user_is_refused(tmp_path, monkeypatch):
    """The peer's uid comes from the kernel (SO_PEERCRED); another user's (here: a faked one)
    is refused before its request is read, whatever the socket's mode lets through."""
    from mavreg.daemon.jobs import endpoint
    real = endpoint.peer_uid
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        assert real(a) in (None, os.geteuid())
    finally:
        a.close()
        b.close()
    monkeypatch.setattr(endpoint, "peer_uid", lambda sock: os.geteuid() + 1)
    resp, server = _serve_hostile(tmp_path, lambda path, _server: request(path, {"op": "land"}, 10))
    assert resp["verdict"] == "refused" and f"uid {os.geteuid() + 1} is not the daemon's user" in resp["reason"]
    assert server.refused == 1
