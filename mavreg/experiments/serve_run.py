"""``mavreg experiment soak|chaos``: draw, fly through ``serve`` (one, or one per shard on
local processes or a Dask cluster), judge, and write ``campaign.json`` and ``campaign.md``."""
from __future__ import annotations

import json
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

from ..config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER, maneuver_file
from .serve_campaign import fly_campaign
from .serve_campaign_report import judge_truth, markdown, summarize
from .serve_draws import FlightDraw, draw_flights

__all__ = ["DEFAULT_FLIGHTS", "Shard", "run_serve_campaign"]

DEFAULT_FLIGHTS = {"soak": 200, "chaos": 300}


@dataclass(frozen=True)
class Shard:
    """Flights flown through one ``serve`` of their own, in ``out_dir``."""

    kind: str
    draws: tuple[FlightDraw, ...]
    out_dir: str
    rate_hz: float


def fly_shard(shard: Shard) -> dict:
    """One shard, flown (in this process: a local worker or a Dask worker); its rows so far are
    in ``rows.jsonl`` of its directory after each flight, so a campaign cut short keeps them."""
    judge = judge_truth if shard.kind == "chaos" else None
    out = Path(shard.out_dir)

    def keep(rows: list[dict]) -> None:
        (out / "rows.jsonl").write_text("".join(json.dumps(r, default=str) + "\n" for r in rows))
        partial = summarize(shard.kind, {"rows": rows, "serve_exit": None, "wall_s": rows[-1].get("wall_s", 0.0)})
        (out / "so-far.md").write_text(markdown(partial, f"(so far, {len(rows)} of {len(shard.draws)} flights)"))
    result = fly_campaign(list(shard.draws), out, shard.rate_hz, judge=judge, on_row=keep,
                          say=lambda line: print(f"[{out.name}] {line}", flush=True))
    keep(result["rows"])                        # with the last world's truth
    for n, row in enumerate(result["rows"], 1):
        row["shard"], row["in_shard"] = Path(shard.out_dir).name, n
    return result


def run_serve_campaign(kind: str, seed: int, flights: int, out_dir: Path, shards: int = 1,
                       dask_address: str | None = None, rate_hz: float = 250.0,
                       command: str = "") -> dict:
    """Draw ``flights`` flights of ``kind`` from ``seed`` and fly them in ``shards`` serves;
    the summary (:func:`~.serve_campaign_report.summarize`), also written to ``out_dir``."""
    draws = draw_flights(kind, seed, flights)
    k = max(1, min(shards, flights))
    todo = [Shard(kind, tuple(draws[i::k]), str(out_dir / (f"shard-{i}" if k > 1 else "serve")), rate_hz)
            for i in range(k)]
    results: list[dict] = []
    if dask_address is not None:
        from .on_dask import run_on_dask
        exp = SimpleNamespace(maneuver_path=maneuver_file("barrel_roll"), vehicle_path=DEFAULT_VEHICLE,
                              controller_path=REAL_CONTROLLER)
        run_on_dask(dask_address, exp, todo, fly_shard, results.append, out_dir)
    elif k == 1:
        results.append(fly_shard(todo[0]))
    else:
        with ProcessPoolExecutor(k) as pool:
            results.extend(pool.map(fly_shard, todo))
    merged = {"rows": sorted((r for res in results for r in res["rows"]), key=lambda r: r["flight"]),
              "serve_exit": [res["serve_exit"] for res in results],
              "wall_s": max(res["wall_s"] for res in results),
              "log_files": max((res["log_files"] for res in results), key=len)}     # the fullest shard's
    summary = summarize(kind, merged)
    summary.update(seed=seed, shards=k, rate_hz=rate_hz, command=command)
    (out_dir / "campaign.json").write_text(json.dumps({"summary": summary, "rows": merged["rows"]},
                                                      indent=1, default=str))
    (out_dir / "campaign.md").write_text(markdown(summary, command))
    return summary
