"""Test-wide setup. pytest puts this directory on ``sys.path`` (rootdir conftest, no
package), so helpers shared by the unit and the end-to-end tests live here once
(``proc_helpers.py``)."""
