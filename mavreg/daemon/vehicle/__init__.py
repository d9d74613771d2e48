"""The vehicle link: bytes and datagrams to MAVLink messages and back.

The asyncio adapters (:mod:`.link` for UDP, :mod:`.stream_link` for serial and TCP,
:mod:`.link_reference` with pymavlink's parser), and the sans-I/O pieces the flight logic uses:
which frames are the vehicle's (:mod:`.peers`), TIMESYNC (:mod:`.timesync`), what differs
between autopilot families (:mod:`.autopilots`), the messages (:mod:`.messages`), the URL
(:mod:`.url`) and the serial-line budget (:mod:`.link_budget`). The codec itself is
:mod:`mavreg.transport`, shared with the emulator.
"""
