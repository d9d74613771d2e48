"""docs/architecture.md names every package and module of mavreg and firmware_sim, and nothing
that is gone; and no document, comment or message of the repository points outside it."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from tests.helpers.repo import ROOT as REPO

DOC = REPO / "docs" / "architecture.md"
_NAMES = re.compile(r"^-\s+((?:`[\w./]+`(?:,\s*|\s+and\s+)?)+):", re.M)


def _packages() -> list[Path]:
    """Every directory of mavreg/ and firmware_sim/ that is a package (has ``__init__.py``)."""
    return sorted(p.parent for top in ("mavreg", "firmware_sim") for p in (REPO / top).rglob("__init__.py"))


def named_in_doc(text: str) -> dict[str, set[str]]:
    """``{"mavreg/daemon": {"link.py", ...}}``: each ``### pkg/`` section's bullet names."""
    sections: dict[str, set[str]] = {}
    for m in re.finditer(r"^### ([\w/]+)/\n(.*?)(?=^#{2,3} |\Z)", text, re.M | re.S):
        body = re.sub(r"\n\s+(?=`)", " ", m.group(2))        # a name list continued on the next line
        sections[m.group(1)] = {n for names in _NAMES.findall(body) for n in re.findall(r"`([\w./]+)`", names)}
    return sections


def missing_and_stale(text: str) -> tuple[list[str], list[str]]:
    """Modules the doc does not name (or whose package has no section), and names it gives that
    do not exist."""
    sections = named_in_doc(text)
    missing, stale = [], []
    for pkg in _packages():
        rel = pkg.relative_to(REPO).as_posix()
        if rel not in sections:
            missing.append(rel + "/")
            continue
        named = sections[rel]
        missing += [f"{rel}/{f.name}" for f in sorted(pkg.glob("*.py"))
                    if f.name != "__init__.py" and f.name not in named]
        stale += [f"{rel}/{n}" for n in sorted(named) if not (pkg / n.rstrip("/")).exists()]
    return missing, stale


def test_every_package_and_module_is_named_and_none_is_stale():
    missing, stale = missing_and_stale(DOC.read_text())
    assert not missing, f"docs/architecture.md does not name: {missing}"
    assert not stale, f"docs/architecture.md names modules that do not exist: {stale}"


def test_the_check_sees_a_module_left_out_and_a_module_made_up():
    text = DOC.read_text()
    assert "- `timesync.py`:" in text
    missing, _ = missing_and_stale(text.replace("- `timesync.py`:", "- timesync:"))
    assert missing == ["mavreg/daemon/vehicle/timesync.py"]
    _, stale = missing_and_stale(text.replace("- `timesync.py`:", "- `timesync.py`, `ghost.py`:"))
    assert stale == ["mavreg/daemon/vehicle/ghost.py"]
    missing, _ = missing_and_stale(text.replace("### mavreg/trackers/", "### trackers"))
    assert "mavreg/trackers/" in missing


@pytest.mark.parametrize("pattern", ["shared/design", "shared/paper", "../shared"])
def test_nothing_points_outside_the_repository(pattern):
    # The one exception: the ArduCopter SITL test harness looks for the simulator next to the
    # repository by default (an environment variable overrides it; tests skip without it).
    found = subprocess.run(["git", "grep", "-n", "-F", pattern, "--", ".", ":!tests/unit/test_architecture_doc.py",
                            ":!harness/ardupilot_sitl.py"],
                           cwd=REPO, capture_output=True, text=True).stdout
    assert found == "", found


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation but ``-`` and ``_``
    dropped, spaces to ``-``."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def broken_anchors(docs: dict[str, str]) -> list[str]:
    """Links ``[..](file.md#anchor)`` or ``[..](#anchor)`` among ``docs`` (name -> text) whose
    anchor is no heading of the file they name."""
    heads = {name: {_slug(h) for h in re.findall(r"^#+ (.*)$", text, re.M)} for name, text in docs.items()}
    bad = []
    for name, text in docs.items():
        for m in re.finditer(r"\]\(([\w./-]*\.md)?#([\w-]+)\)", text):
            target = (m.group(1) or name).rsplit("/", 1)[-1]
            if target in heads and m.group(2) not in heads[target]:
                bad.append(f"{name}: {m.group(0)}")
    return bad


def test_every_link_to_a_heading_finds_it():
    """A heading that names a module moves with the module (issue 31's rooms renamed many):
    every link to it must follow, or it lands at the top of the page."""
    docs = {p.name: p.read_text() for p in (REPO / "docs").glob("*.md")}
    assert broken_anchors(docs) == []
    fake = {"a.md": "## The rotor lag (`mavreg/control/design/actuator.py`)\n## split_s\n",
            "b.md": "[x](a.md#the-rotor-lag-mavregcontroldesignactuatorpy) [y](a.md#split_s) "
                    "[z](a.md#the-rotor-lag-mavregcontrolactuatorpy) [w](#nowhere)\n"}
    assert broken_anchors(fake) == ["b.md: ](a.md#the-rotor-lag-mavregcontrolactuatorpy)", "b.md: ](#nowhere)"]
