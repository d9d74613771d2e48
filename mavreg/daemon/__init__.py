"""The mavreg daemon: sans-I/O flight supervisor plus a thin asyncio MAVLink adapter."""
