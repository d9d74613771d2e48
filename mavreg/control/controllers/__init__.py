"""The flight controllers: the maneuver regulator (:mod:`.regulator`, its compiled step
:mod:`.fastpath` and :mod:`.step_kernel`), the speed governor (:mod:`.governor`), the hover LQR
(:mod:`.hover`), the recovery controller (:mod:`.recovery`), and the warm-up that compiles the
per-sample kernels before the loop (:mod:`.sample_warmup`)."""
