"""firmware_sim: a software-in-the-loop quadrotor that speaks MAVLink 2 over UDP, a pty, a serial port or TCP.

Its own physics (quaternion rigid body with the full inertia matrix, RK4, rotor lag,
noise, drag, wind, ground contact), a small sans-I/O autopilot (arming, modes,
offboard stream, failsafe stabilizer, TIMESYNC), a UDP link, a world between them (link
delay, jitter and loss in sim time; a late, noisy state estimate; presets ``realistic``
and ``ideal``), two clocks (real time and lockstep) and a flight recorder. It imports
nothing from ``mavreg`` but ``mavreg.config`` and ``mavreg.transport`` (the MAVLink codec,
signing and byte streams: the specification's, shared with the daemon).
See ``docs/firmware_sim.md``.
"""
__all__ = ["__version__"]
__version__ = "0.1.0"
