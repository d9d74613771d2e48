"""``mavreg experiment``: rerun the paper's Section 4 and write its tables and figures."""
from __future__ import annotations

import os
import shlex
import time
from pathlib import Path

from ..errors import UsageError
from .common import check_output_dir

HELP = ("rerun the paper's experiments (Section 4) and its Fig. 1 against time-indexed trackers, "
        "on the design model or over MAVLink; tables and figures")
DESCRIPTION = """\
Fly every run of an experiment, in parallel over --jobs processes (or on a Dask cluster,
--dask), and write into --out: PNG figures, results.json (every number of every run) and
results.md (the tables). A progress line goes to stderr. Runs are seeded from --seed and the
results depend on neither --jobs nor --dask.

Experiments (NAME):
  paper-group1  start 0.6 m off in each of p1, p2, p3 (1.04 m from the entry); one run on the
                nominal inertia and 25 on jx, jy, jz drawn with SD 0.0102/3 kg m^2; the design
                is always the nominal one. Table per run: converged (transverse error below
                1 cm from then until the run-up ends), the arc length where it did, loop max
                and RMS transverse error, loop max attitude error, peak thrust and torques.
                Figures: fig2_inertia_paths, fig3_attitude_velocity, fig4_inputs, errors.
  paper-group2  nominal start, 0.1 N Gaussian noise on each rotor force, rotor saturation
                none / 8.5 N / 7 N, the loop flown 3 times. Table: stable (flown to the end and
                back within 10 cm of the path), laps, max and RMS transverse error, max
                attitude error, time saturated. Figures: fig5_rotor_forces, fig6_paths,
                fig7_attitude_velocity, errors.
  gust          the scenario of the paper's Fig. 1: a force of 5, 8 or 10 N against the path's
                tangent for 1 s, on the run-up at speed (s = 11 m), early in the run-up at low
                speed (s = 2 m) and at the start of the loop; maneuver regulation (paper_lqr.yaml)
                against two time-indexed trackers of the same nominal, a time-varying LQR and
                the SE(3) tracker of Lee, Leok and McClamroch; ideal rotors and 12 N rotors.
                Table: max distance from the path, time outside a 0.5 m tube, peak
                acceleration, min distance to the loop's centre, overspeed against the
                profile, diverged. Figures per place: paths, distance and speed against time.
  lag           the trackers' timed reference 1, 2 or 4 m ahead of a vehicle on the nominal at
                s = 11 m (as after a gust that held it back); the same table and figures.
  robustness    the product as shipped (mavreg fly's default controller, realistic.yaml, its
                envelope untouched, on the realistic world) over a matrix of cells, one factor
                at a time: wind 3 m/s from 8 directions and 6 m/s from 4, thrust 90 %, an 8 N
                gust at the gust experiment's three places, 8.5 and 7 N rotors, airframes
                drawn by the emulator (--mismatch-seed), round trips 0-60 ms, 5 % loss, no
                TIMESYNC, estimator errors x2, every other maneuver file. --flights N seeds
                per cell (default 2), --cells GROUP,CELL,... a subset (e.g. mismatch,gust).
                Table per cell: ok / failed but safe / unsafe (motors stopped in the air or a
                ground impact over 1 m/s), error statistics, lowest altitude; every flight
                that was not ok with its cause. Figure: robustness_cells. Default --via sitl;
                --via sim flies the maneuver alone with the same controller on the design
                model in a realistic-like world (rotor lag, delays, estimator errors): the
                cells it can represent (not wind, loss, no-timesync), judged by the truth's
                errors and whether the maneuver reached its end.

  soak          one 'mavreg serve' against the emulator in lockstep flies --flights flights
                (default 200) back to back, uploaded through its endpoint: the hop, library
                maneuvers and laps, a rejected upload every fifth flight. Measures the serve's
                and its planner worker's memory, descriptors and threads after each flight
                (their growth from flight 20 on), the latency and every flight's outcome.
  chaos         --flights (default 300) through one serve, each in a world drawn from --seed:
                link faults (loss, bursts, reordering, outages), gusts, an airframe drawn
                around the vehicle file, the host loaded on every core, hostile uploads; the
                emulator restarts before each flight (a vehicle reboot between flights). Counts
                each outcome, unsafe events on the emulator's truth (touchdown over 1 m/s,
                motors stopped in the air, an arm not asked for) and lost results.
                soak and chaos take --jobs N (N serves, the flights dealt out; default 1) or
                --dask; they write campaign.json and campaign.md (docs/reliability.md).

--via sim (default) flies the design model (RK4 at 1 ms, regulator at 1 kHz; about 5 s of CPU
a run). --via sitl flies each run with 'mavreg fly --lockstep --world ideal' against the
bundled firmware_sim over MAVLink (about 15-40 s a run): the plant's inertia, rotor noise and
saturation go to the emulator only (the daemon designs on the 12 N nominal), the start offset
is 'mavreg fly --entry-offset', the laps a maneuver file written into --out, and the
controller file is paper_lqr.yaml with a maneuver envelope wide enough for the paper's
deliberate errors (controller_experiment.yaml in --out). Each flight's summary, plot and log
stay in --out/runs/NNN/. Errors are always the truth's (the emulator's recording).

Via sitl only maneuver regulation flies (the daemon flies the regulator): gust is its nine
runs on the emulator's 12 N rotors, the force window given to firmware_sim (--wind
force:...@T0:T1) at the maneuver's start measured by a gust-free reference flight; lag does
not fly via sitl.

--dask ADDRESS runs on an existing Dask cluster (pip install 'mavreg[dask]'); the workers need
the same mavreg and the experiment's files at the same paths (checked before any run), and
via sitl --out on a shared filesystem.

Exit status: 0 every run met its criterion (converged before the loop / stable / reached the
path's end / robustness: the flight ok, nothing unsafe), 1 some run did not or could not be flown (the results are written all the same),
2 bad input.
See docs/experiments.md and docs/results.md.
"""


def add_arguments(p):
    p.add_argument("name", metavar="NAME", help=f"the experiment: {', '.join(_names())}")
    p.add_argument("--out", metavar="DIR", default=None,
                   help="output directory (default: experiments/NAME-VIA-<YYYYmmdd-HHMMSS>/)")
    p.add_argument("--seed", metavar="N", default="0",
                   help="seed of the inertia draws and the rotor noise (default 0)")
    p.add_argument("--jobs", metavar="N", default=None,
                   help="worker processes (default: the number of CPUs, here %d); on a 2-core machine "
                   "use 1 or 2 with --via sitl" % (os.cpu_count() or 1))
    p.add_argument("--via", metavar="sim|sitl", default=None,
                   help="sim: the design model (default; robustness: sitl); sitl: the daemon and "
                   "firmware_sim in lockstep")
    p.add_argument("--flights", metavar="N", default=None,
                   help="robustness: flights (seeds) per cell (default 2); soak, chaos: flights in all "
                   "(default 200, 300)")
    p.add_argument("--cells", metavar="LIST", default=None,
                   help="robustness: only these cells or groups, comma-separated (default: all; groups: "
                   "baseline, wind3, wind6, thrust90, gust, rotors, mismatch, delay, loss, timesync, "
                   "estimator, maneuvers)")
    p.add_argument("--dask", metavar="ADDRESS", default=None,
                   help="run on the Dask cluster whose scheduler is at ADDRESS (e.g. tcp://host:8786) "
                   "instead of a local process pool; needs dask.distributed")
    p.add_argument("--keep-flight-files", action="store_true",
                   help="--via sitl: keep each flight's .tlog, control.npz and groundtruth.npz "
                   "(about 17 MB a flight; by default only summary.json, flight.png and fly.log stay)")


def _whole(text: str, what: str, minimum: int) -> int:
    try:
        n = int(text)
    except (TypeError, ValueError):
        raise UsageError(f"{what} must be a whole number, got {text!r}") from None
    if n < minimum:
        raise UsageError(f"{what} must be at least {minimum}, got {n}")
    return n


SERVE_CAMPAIGNS = ("soak", "chaos")


def _names() -> list[str]:
    from ..experiments.definitions import EXPERIMENTS
    return [*EXPERIMENTS, "robustness", *SERVE_CAMPAIGNS]


def _serve_campaign(args) -> int:
    """``soak`` and ``chaos``: flights through one ``serve`` (:mod:`mavreg.experiments.serve_run`)."""
    from ..experiments.serve_run import DEFAULT_FLIGHTS, run_serve_campaign
    if args.via is not None or args.cells is not None or args.keep_flight_files:
        raise UsageError(f"{args.name} flies through mavreg serve: --via, --cells and --keep-flight-files "
                         "do not apply")
    if args.dask is not None and args.jobs is not None:
        raise UsageError("--jobs sizes the local process pool; with --dask the cluster's workers fly the serves")
    seed = _whole(args.seed, "--seed", 0)
    flights = DEFAULT_FLIGHTS[args.name] if args.flights is None else _whole(args.flights, "--flights", 1)
    jobs = 1 if args.jobs is None else _whole(args.jobs, "--jobs", 1)
    if args.dask is not None:
        from ..experiments.on_dask import require_dask
        require_dask()
    out = Path(args.out) if args.out else Path("experiments") / f"{args.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    why = check_output_dir(str(out))
    if why is not None:
        raise UsageError(f"--out {why}")
    out.mkdir(parents=True, exist_ok=True)
    command = (f"mavreg experiment {args.name} --seed {seed} --flights {flights} "
               + (f"--dask {shlex.quote(args.dask)} " if args.dask else f"--jobs {jobs} ")
               + f"--out {shlex.quote(str(out))}")
    sm = run_serve_campaign(args.name, seed, flights, out, jobs, args.dask, command=command)
    ok = sm["outcomes"].get("ok", 0)
    print(f"{args.name}: {ok} of {sm['flights']} flights ok, {len(sm['unsafe'])} unsafe, "
          f"{len(sm['lost_results'])} results lost, {sm['hostile_not_rejected']} hostile uploads not rejected")
    print(f"outputs: {out}/ (campaign.json, campaign.md)")
    return 0 if not sm["unsafe"] and not sm["lost_results"] and not sm["hostile_not_rejected"] else 1


def _build(args, seed: int):
    """The experiment ``args.name`` drawn from ``seed``, as flown ``args.via``."""
    from ..experiments.definitions import build_experiment
    if args.name != "robustness":
        return build_experiment(args.name, seed, args.via)
    from ..experiments.robustness import DEFAULT_FLIGHTS, check_emulator, robustness
    flights = DEFAULT_FLIGHTS if args.flights is None else _whole(args.flights, "--flights", 1)
    exp = robustness(seed, flights, args.cells)        # the cells checked before the via
    if args.via == "sim":
        from ..experiments.robustness_sim import robustness_via_sim
        return robustness_via_sim(seed, flights, args.cells)
    check_emulator(exp)
    return exp


def run(args) -> int:
    from ..experiments.campaign import run_campaign
    from ..experiments.runner import VIAS
    if args.name not in _names():
        raise UsageError(f"unknown experiment {args.name!r}; choose one of {', '.join(_names())}")
    if args.name in SERVE_CAMPAIGNS:
        return _serve_campaign(args)
    robust = args.name == "robustness"
    if args.via is None:
        args.via = "sitl" if robust else "sim"
    if args.via not in VIAS:
        raise UsageError(f"--via must be one of {', '.join(VIAS)}, got {args.via!r}")
    seed = _whole(args.seed, "--seed", 0)
    jobs = (os.cpu_count() or 1) if args.jobs is None else _whole(args.jobs, "--jobs", 1)
    if args.keep_flight_files and args.via != "sitl":
        raise UsageError("--keep-flight-files applies only to --via sitl")
    if not robust and (args.flights is not None or args.cells is not None):
        raise UsageError("--flights and --cells apply only to the robustness experiment")
    exp = _build(args, seed)
    if args.dask is not None and args.jobs is not None:
        raise UsageError("--jobs sizes the local process pool; with --dask the cluster's workers fly the runs")
    if args.dask is not None:
        from ..experiments.on_dask import require_dask
        require_dask()
    out = Path(args.out) if args.out else (Path("experiments")
                                           / f"{args.name}-{args.via}-{time.strftime('%Y%m%d-%H%M%S')}")
    why = check_output_dir(str(out))
    if why is not None:
        raise UsageError(f"--out {why}")
    out.mkdir(parents=True, exist_ok=True)
    command = (f"mavreg experiment {args.name} --via {args.via} --seed {seed} "
               + (f"--flights {exp.flights} " if robust else "")
               + (f"--cells {shlex.quote(args.cells)} " if robust and args.cells else "")
               + (f"--dask {shlex.quote(args.dask)} " if args.dask else f"--jobs {jobs} ")
               + f"--out {shlex.quote(str(out))}" + (" --keep-flight-files" if args.keep_flight_files else ""))
    camp = run_campaign(exp, args.via, jobs, out, command, keep_flight_files=args.keep_flight_files,
                        dask_address=args.dask, argv=getattr(args, "command_line", None))
    sm = camp.results["summary"]
    crit = ("ok (flown, landed, nothing unsafe)" if robust and args.via == "sitl"
            else "converged before the loop" if "converged" in sm
            else "stable" if "stable" in sm else "flown to the path's end")
    print(f"{exp.name} via {args.via}: {sm['ok']} of {sm['runs']} runs {crit}"
          + (f", {sm['errors']} could not be flown" if sm["errors"] else ""))
    print(f"outputs: {out}/ (" + ", ".join(f.name for f in camp.files) + ")")
    return 0 if camp.all_ok else 1
