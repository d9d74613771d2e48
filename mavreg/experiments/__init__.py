"""``mavreg experiment``: the paper's Section 4 rerun, and its Fig. 1 measured, with tables and figures.

One concept per module:

- :mod:`.definitions`: what each experiment flies (runs, seeds, inertia draws, gusts, leads);
- :mod:`.via_sim` and :mod:`.via_sitl`: fly one run on the design model (the regulator or a
  time-indexed tracker of :mod:`mavreg.trackers`), or with the daemon against firmware_sim in
  lockstep over MAVLink; both leave a :class:`.record.Flight`;
- :mod:`.record`: the true record and its errors against the plan, sample by sample;
- :mod:`.metrics`: the numbers of the paper groups' tables (convergence, loop errors,
  saturation, laps); :mod:`.disturbance_metrics`: those of the gust and lag tables;
- :mod:`.runner`: the process pool and the progress line; :mod:`.on_dask`: the same jobs on a
  Dask cluster;
- :mod:`.figures`, :mod:`.figures_disturbance` and :mod:`.report`: the PNGs, ``results.json``
  and ``results.md``;
- :mod:`.campaign`: all of it for one experiment (what the CLI calls).
"""
