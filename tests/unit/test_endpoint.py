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
