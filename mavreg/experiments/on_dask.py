"""Fly an experiment's runs on an existing Dask cluster (``mavreg experiment --dask ADDRESS``).

The same jobs as the process pool (:mod:`.runner`), each complete in itself and flown from
scratch by one worker, so the results are those of the local runner for the same seed, float
for float (tests/unit/test_experiment_dask.py against a ``LocalCluster``). ``dask.distributed``
is an optional dependency (``pip install 'mavreg[dask]'``); without it ``--dask`` is a one-line
error.

What the workers need: the same mavreg (checked: the digest of its Python sources,
:func:`mavreg.planning.cache.code_digest`) and the experiment's files at the same paths with
the same contents (checked: SHA-256 of the maneuver, vehicle and controller files), which a
shared checkout or the same container image gives. A ``sitl`` run also writes its flight into
``--out``, which the workers must see at the same path (a shared filesystem), and runs the
bundled firmware_sim as a process on the worker. Every check is made on every worker before
any run starts; a mismatch is one error naming the worker.
"""
from __future__ import annotations

import os
from pathlib import Path

from ..errors import UsageError

__all__ = ["require_dask", "run_on_dask", "worker_probe", "CONNECT_TIMEOUT_S"]

CONNECT_TIMEOUT_S = 30.0


def require_dask():
    """The ``distributed`` module; ValueError with the way to install it when it is missing."""
    try:
        import distributed
    except ImportError:
        raise UsageError("--dask needs dask.distributed, which is not installed: "
                         "pip install 'mavreg[dask]' (or 'dask[distributed]')") from None
    return distributed


def worker_probe(files: list[str], out_dir: str | None) -> dict:
    """What a worker has: mavreg's code digest, each file's SHA-256 (None: unreadable), and
    whether ``out_dir`` is a writable directory there (None: not asked). The digest is read
    afresh (not the process's first, cached reading): the sources as they are now."""
    from ..planning.cache import code_digest
    from ..provenance import file_sha256
    return {"code": code_digest.__wrapped__(), "files": {f: file_sha256(f) for f in files},
            "out_dir": None if out_dir is None else (os.path.isdir(out_dir) and os.access(out_dir, os.W_OK))}


def _check_workers(client, exp, out_dir: Path | None) -> None:
    paths = (exp.maneuver_path, exp.vehicle_path, exp.controller_path,
             *(c.maneuver_path for c in getattr(exp, "cells", ())))    # robustness: every cell's maneuver
    files = list(dict.fromkeys(str(Path(p).resolve()) for p in paths))
    want = worker_probe(files, None if out_dir is None else str(out_dir))
    got = client.run(worker_probe, files, None if out_dir is None else str(out_dir))
    if not got:
        raise UsageError("the Dask cluster has no workers")
    for worker, have in sorted(got.items()):
        if have["code"] != want["code"]:
            raise UsageError(f"Dask worker {worker} runs another mavreg (code digest {have['code'][:12]}, "
                             f"here {want['code'][:12]}): install the same version on the workers")
        for f in files:
            if have["files"][f] != want["files"][f]:
                what = "cannot read" if have["files"][f] is None else "has another version of"
                raise UsageError(f"Dask worker {worker} {what} {f}: the workers need the experiment's "
                                 "files at the same paths")
        if out_dir is not None and not have["out_dir"]:
            raise UsageError(f"Dask worker {worker} cannot write {out_dir}: a sitl campaign needs --out "
                             "on a filesystem the workers share")


def run_on_dask(address: str, exp, todo, execute, on_outcome, needs_out_dir: Path | None) -> None:
    """Submit every job of ``todo`` to the scheduler at ``address``, call ``execute`` on a
    worker for each, and ``on_outcome`` here with each result as it comes.

    Raises
    ------
    ValueError
        dask.distributed missing, the scheduler unreachable, or a worker unfit (see the module
        docstring).
    """
    distributed = require_dask()
    try:
        client = distributed.Client(address, timeout=f"{CONNECT_TIMEOUT_S:g}s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise UsageError(f"--dask {address}: cannot reach the Dask scheduler: {exc}") from None
    with client:
        _check_workers(client, exp, needs_out_dir)
        futures = client.map(execute, todo, pure=False)
        try:
            for fut in distributed.as_completed(futures, loop=client.loop):
                on_outcome(fut.result())
        except BaseException:                      # Ctrl-C, a lost worker: drop what is left
            client.cancel(futures)
            raise
