"""Rigs that fly mavreg on something other than its own daemon loop, shared by the tests, the
benchmarks and the scripts: the stock autopilots' SITL (PX4 with SIH, ArduCopter) started,
configured and flown through MAVLink (:mod:`.px4_sitl`, :mod:`.ardupilot_sitl`,
:mod:`.sitl_link`, :mod:`.px4_flight`, :mod:`.ardupilot_flight`, and their own position
controllers flown on the same paths, :mod:`.autopilot_baseline_flight`), PX4's rate-step
measurement (:mod:`.px4_rate_step`), the controller flown in-process on the design model
(:mod:`.controller_flight`, and the plain-Python regulator it is timed against,
:mod:`.plain_regulator`), the bundled parameters loaded once (:mod:`.params`) and child
processes started and stopped (:mod:`.processes`).

Not part of the installed package: it runs from a checkout, as ``tests/``, ``benchmarks/`` and
``scripts/`` do, and imports nothing from ``tests/`` (``tests/unit/test_tests_layout.py``).
"""
