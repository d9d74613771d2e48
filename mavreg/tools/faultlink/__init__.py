"""A fault-injecting MAVLink link, for tests: loss (rate and bursts), delay with jitter,
reordering, duplication, corruption and outages, each seeded.

- :mod:`.model`: the sans-I/O core, :class:`FaultLine` (one direction; items in with a
  time, out later), used by the unit tests and by firmware_sim's lockstep shim
  (``firmware_sim --link-faults``), which applies it in vehicle time; and
  :class:`ByteLoss`, a serial line that loses bytes (``firmware-sim --serial-byte-loss``);
- :mod:`.proxy`: an asyncio UDP proxy between a daemon and a vehicle, both directions
  faulted in wall-clock time: ``python -m mavreg.tools.faultlink --help``.

docs/reliability.md ("Link faults") describes both and the flights flown through them.
"""
from .model import ByteLoss, FaultCounters, FaultLine, FaultParams, flip_bits, parse_faults

__all__ = ["ByteLoss", "FaultCounters", "FaultLine", "FaultParams", "flip_bits", "parse_faults"]
