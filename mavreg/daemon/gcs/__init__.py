"""The ground-station bridge: what goes to a ground station, what may come back (sans-I/O
:mod:`.bridge` and :mod:`.policy`, the options :mod:`.params`), and its UDP adapter
:mod:`.link`."""
