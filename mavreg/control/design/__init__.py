"""Design-time mathematics of the maneuver regulator: transverse coordinates and their
s-domain linearization (:mod:`.transverse`, :mod:`.actuator`), the s-varying Riccati sweep
(:mod:`.riccati`, its step :mod:`.riccati_step` and kernel :mod:`.riccati_kernel`) and the
loop's gain and delay margins (:mod:`.margins`)."""
