"""``mavreg experiment``: the paper's Section 4 rerun, with its tables and figures.

One concept per module:

- :mod:`.definitions`: what each experiment flies (runs, seeds, inertia draws);
- :mod:`.via_sim` and :mod:`.via_sitl`: fly one run on the design model, or with the daemon
  against firmware_sim in lockstep over MAVLink; both leave a :class:`.record.Flight`;
- :mod:`.record`: the true record and its errors against the plan, sample by sample;
- :mod:`.metrics`: the numbers of the tables (convergence, loop errors, saturation, laps);
- :mod:`.runner`: the process pool and the progress line;
- :mod:`.figures` and :mod:`.report`: the PNGs, ``results.json`` and ``results.md``;
- :mod:`.campaign`: all of it for one experiment (what the CLI calls).

Not here: the gust and lag experiments, the time-indexed trackers and ``--dask`` (issue 9).
"""
