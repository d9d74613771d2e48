"""Fuzzing of the two MAVLink receive paths (the daemon's and firmware_sim's).

``python -m fuzz --help``: a long, seeded run over millions of frames that prints the frames
run per target and what it found; the bounded property tests of the default suite
(``tests/unit/test_fuzz_daemon.py``, ``tests/firmware_sim/test_fuzz_fsim.py``) use the same
generators (:mod:`fuzz.frames`) and checks (:mod:`fuzz.targets`). docs/reliability.md,
"Fuzzing", has the figures.
"""
