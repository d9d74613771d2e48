"""The repository's root directory, for the tests that read its files (docs, scripts, the
emulator's sources) or start a child process in it. Parameter files are not found through
it: ask :mod:`mavreg.config.paths` (or :mod:`harness.params`)."""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
