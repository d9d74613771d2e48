"""Planning with files: maneuver files and uploads planned through the on-disk plan cache, and
the nominal written to and read from files.

The adapter around the pure planner (:mod:`mavreg.maneuver`): the I/O of planning lives
here, so that the core reads no file. Import from the modules (``plan_io``, ``cache``,
``nominal_files``); this package imports nothing heavy by itself.
"""
