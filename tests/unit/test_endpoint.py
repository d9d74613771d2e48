"""Control endpoint: mode 0600, JSON lines, oversized and malformed requests refused."""
import asyncio
import json
import os
import socket
import stat

import pytest

from mavreg.daemon.endpoint import (MAX_REQUEST_BYTES, EndpointServer, RequestError, default_socket_path,
                                    request, validate_request)


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
        await asyncio.sleep(60)   # an upload being planned
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
