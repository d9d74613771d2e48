"""What the controllers estimate in flight: the state predicted across the link
(:mod:`.predictor`, :mod:`.forecast`), the disturbance observer (:mod:`.disturbance`, with its
torque-bias and rotor-lag parts :mod:`.torque_bias` and :mod:`.lag_observer`)."""
