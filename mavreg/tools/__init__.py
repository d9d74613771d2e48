"""Tools for testing a MAVLink setup (not used by the daemon's flight path)."""
