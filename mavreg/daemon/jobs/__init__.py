"""What runs: the ``fly`` job (:mod:`.fly`), the asyncio daemon behind ``fly`` and ``serve``
(:mod:`.app`, with :mod:`.vehicle_io`, :mod:`.endpoint`, :mod:`.startup`, :mod:`.sdnotify`),
the planner worker (:mod:`.planner_pool`), child processes that die with the daemon
(:mod:`.lifeline`), the flights one after another (:mod:`.flight_sequence`,
:mod:`.flight_book`) and what each leaves behind (:mod:`.ctrllog`, :mod:`.report`)."""
