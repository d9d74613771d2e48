"""The mavreg daemon, in five rooms, each importing only the rooms below it:

- :mod:`.jobs`: what runs: the ``fly`` job, the asyncio daemon ``serve`` runs (its control
  endpoint, the planner worker, start-up and systemd), the flights one after another and their
  logs and reports.
- :mod:`.gcs`: the ground-station bridge: what is forwarded, what a ground station may ask,
  and its UDP adapter.
- :mod:`.flight`: the flight logic, sans-I/O: the supervisor and its parts (phases, handlers,
  safety, health gate, envelope monitor, reboots, records). Numbers and messages in, commands
  and records out; no event loop, socket or clock (an import contract holds it so).
- :mod:`.vehicle`: the vehicle link: the UDP, serial and TCP adapters, which frames are the
  vehicle's (peers, signing), TIMESYNC, the autopilot families' dialects and messages.
- :mod:`.logs`: the files written while flying (the ``.tlog``) and what a write error does to
  them: never the flight.
"""
