"""The controllers, in three rooms, each importing only the ones below it:

- :mod:`.controllers`: what flies: the maneuver regulator (paper eq 33) and its compiled step,
  the speed governor, the hover LQR and its ramps, the recovery controller.
- :mod:`.estimation`: what the controllers need to know: the state predicted across the link,
  the disturbance observer (torque bias, rotor lag, drag) and the commands sent.
- :mod:`.design`: design-time mathematics: transverse coordinates and their linearization
  (rotor lag included), the s-varying Riccati sweep, gain and delay margins.
"""
