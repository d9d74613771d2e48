"""Time-indexed trackers of a planned maneuver: what maneuver regulation is compared with.

Maneuver regulation (:mod:`mavreg.control.controllers.regulator`) schedules its feedback on the arc
length of the vehicle's projection on the path: it has no clock. The classical alternative
tracks the same nominal as a *trajectory*, a reference that moves on in time whether the
vehicle keeps up or not. Spedicato et al.'s Fig. 1 is the argument: a vehicle held back
by a gust is pulled towards where the reference has got to, and cuts the corners of the
maneuver to catch up. ``mavreg experiment gust|lag`` measures it with two trackers on the
same nominal as the regulator:

- :mod:`.timed`: the plan's nominal timed by its speed profile, ``s(t)`` from
  ``ds/dt = v(s)``, with the reference state, input and accelerations at any time;
- :mod:`.tvlqr`: a time-varying LQR on the full state, with the Riccati equation solved
  backward in time along the timed nominal;
- :mod:`.se3`: the geometric tracking controller on SE(3) of Lee, Leok and McClamroch
  ("Geometric tracking control of a quadrotor UAV on SE(3)", CDC 2010);
- :mod:`.common`: what a tracker returns and how it turns a wrench into rotor forces
  (the regulator's allocation).

Both are pure controllers: ``step(t, x)`` with the maneuver time t and the design model's
state x returns rotor forces. Pure numbers, no I/O.
"""
