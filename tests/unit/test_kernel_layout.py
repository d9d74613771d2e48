"""The kernel convention (docs/architecture.md, "Kernel convention"): a kernel (a function under
``mavreg.accel.njit``) lives only in a ``*_kernel.py`` file, every such file declares one, and
every one is a row of the document's kernel table. Four layouts grew before this held: kernels
inside the API module, both forms in the kernel file, a ``_compiled`` suffix."""
from __future__ import annotations

import ast
import re

from tests.helpers.repo import ROOT

DOC = ROOT / "docs" / "architecture.md"


def declares_kernel(source: str) -> bool:
    """Whether ``source`` defines a function decorated ``@njit`` (bare, called, or ``accel.njit``)."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for dec in node.decorator_list:
                target = dec.func if isinstance(dec, ast.Call) else dec
                name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", None)
                if name == "njit":
                    return True
    return False


def layout_findings(files: dict[str, str], table: str) -> list[str]:
    """What breaks the convention among ``files`` (path relative to ``mavreg/`` -> source)."""
    found = []
    for rel, source in sorted(files.items()):
        kernel_file = rel.endswith("_kernel.py")
        has = declares_kernel(source)
        if has and not kernel_file:
            found.append(f"{rel}: declares a kernel outside a *_kernel.py file")
        if kernel_file and not has:
            found.append(f"{rel}: a *_kernel.py file that declares no kernel")
        if kernel_file and f"`{rel}`" not in table:
            found.append(f"{rel}: not in the kernel table of docs/architecture.md")
    return found


def _table() -> str:
    text = DOC.read_text()
    return re.search(r"^\| concept \| numpy reference \| kernel \|.*?(?=\n\n)", text, re.M | re.S).group(0)


def _mavreg_sources() -> dict[str, str]:
    root = ROOT / "mavreg"
    return {p.relative_to(root).as_posix(): p.read_text(encoding="utf-8") for p in root.rglob("*.py")
            if p.name != "accel.py"}


def test_every_kernel_is_in_a_kernel_file_and_in_the_table():
    assert layout_findings(_mavreg_sources(), _table()) == []


def test_the_check_sees_each_way_out_of_the_layout():
    kernel = "from ..accel import njit\n\n@njit\ndef f(x):\n    return x\n"
    plain = "def f(x):\n    return x\n"
    table = "| rotor lag | `model/rotor_lag.py` | `model/rotor_lag_kernel.py` | t |"
    assert layout_findings({"model/rotor_lag_kernel.py": kernel, "model/rotor_lag.py": plain}, table) == []
    assert layout_findings({"control/observer.py": kernel.replace("@njit", "@accel.njit()")}, table) == [
        "control/observer.py: declares a kernel outside a *_kernel.py file"]
    assert layout_findings({"model/rotor_lag_kernel.py": plain}, table) == [
        "model/rotor_lag_kernel.py: a *_kernel.py file that declares no kernel"]
    assert layout_findings({"sim/batch_kernel.py": kernel}, table) == [
        "sim/batch_kernel.py: not in the kernel table of docs/architecture.md"]
