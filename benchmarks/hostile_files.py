"""Every hostile case through ``mavreg plan`` in its own process: the figures of
docs/reliability.md, "Hostile files".

    python benchmarks/hostile_files.py [--json OUT]

Runs the corpus of tests/data/hostile/, the barrel roll with each required key missing, and
the big cases (100 MB, /dev/zero, 100 000 waypoints, 100 000-deep nesting, --laps 100,
riccati_step_s 1e-9 ...), each as ``python -m mavreg.cli.main plan`` without the plan cache,
and reports how many gave a clean error (exit 2, one line on stderr, no traceback, at most
600 characters), the slowest and the largest (peak RSS of that process), and the cost of
starting the CLI (a missing file). On a shared machine a process's time is mostly starting
Python and importing mavreg, so each case is also timed through the CLI's ``main`` in this
process (the refusal's own cost). About 2 s a case on a quiet core.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import json
import sys
import tempfile
import time
from pathlib import Path

HOSTILE = Path(__file__).resolve().parents[1] / "tests" / "data" / "hostile"


def _generator():
    spec = importlib.util.spec_from_file_location("hostile_generate", HOSTILE / "generate.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _clean(rc: int, err: str) -> bool:
    return (rc == 2 and err.endswith("\n") and err.count("\n") == 1 and "Traceback" not in err
            and len(err) <= 600)


def _in_process(cases: dict[str, list[str]]) -> dict[str, float]:
    """Seconds of ``mavreg plan ARGS`` through the CLI's main in this process, per case (the
    CLI's modules imported once, first)."""
    from mavreg.cli.main import main as cli_main
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        cli_main(["plan", "/nonexistent.yaml"])
    out = {}
    for name, case_args in cases.items():
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            cli_main(["plan", *case_args])
        out[name] = time.perf_counter() - t0
        sink.seek(0)
        sink.truncate()
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", metavar="OUT", help="write every case's figures here")
    args = ap.parse_args(argv)
    gen = _generator()
    rows = []
    with tempfile.TemporaryDirectory(prefix="hostile-") as d:
        tmp = Path(d)
        cases = {p.name: [str(p)] for p in sorted(HOSTILE.glob("*.yaml"))}
        for name, text in gen.missing_key_cases().items():
            f = tmp / (name.replace(" ", "_") + ".yaml")
            f.write_text(text)
            cases[name] = [str(f)]
        cases.update(gen.big_cases(tmp))
        own = _in_process(cases)
        for name, case_args in cases.items():
            rc, err, seconds, rss_mb = gen.run_measured(case_args, tmp)
            rows.append({"case": name, "exit": rc, "clean": _clean(rc, err), "seconds": seconds,
                         "in_process_s": own[name], "rss_mb": rss_mb, "stderr_chars": len(err),
                         "stderr": err[:200].strip()})
            print(f"{seconds:6.2f} s {rss_mb:6.0f} MB  exit {rc}  {name}: {err[:120].strip()}",
                  flush=True)
    startup = next(r for r in rows if r["case"].startswith("startup"))
    hostile = [r for r in rows if r is not startup]
    slow = max(hostile, key=lambda r: r["seconds"])
    slow_own = max(hostile, key=lambda r: r["in_process_s"])
    big = max(hostile, key=lambda r: r["rss_mb"])
    print(f"\n{len(hostile)} hostile cases, {sum(r['clean'] for r in hostile)} clean one-line "
          f"errors with exit 2; longest message {max(r['stderr_chars'] for r in hostile)} chars")
    print(f"slowest {slow['seconds']:.2f} s ({slow['case']}), largest {big['rss_mb']:.0f} MB "
          f"({big['case']}); starting the CLI alone: {startup['seconds']:.2f} s, "
          f"{startup['rss_mb']:.0f} MB")
    print(f"in one process (no start-up): slowest {slow_own['in_process_s']:.3f} s "
          f"({slow_own['case']}), median {sorted(r['in_process_s'] for r in hostile)[len(hostile) // 2]:.3f} s")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0 if all(r["clean"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
