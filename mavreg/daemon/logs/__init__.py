"""The files written while flying: the ``.tlog`` (:mod:`.tlog`) and what a write error does to
any of the daemon's files (:mod:`.outputs`): never the flight."""
