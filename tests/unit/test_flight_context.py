"""Who writes the flight's shared state (docs/architecture.md, *The supervisor*): every field of
:class:`~mavreg.daemon.flight.context.FlightContext` (its groups opened) names in its docstring the
module that writes it (``Writer: verbs.``), or the modules that share it and why (``Writers: a, b;
shared: ...``). The check reads the source: every assignment to a field through a ``ctx``, every
mutating call on one (``append``, ``clear``, ...) and every mutable field handed to a function is a
write by its module, and the writers found must be the writers declared. A new writer, one gone,
or a second one without a reason fails."""
from __future__ import annotations

import ast
import re

from tests.helpers.repo import ROOT

CONTEXT = ROOT / "mavreg" / "daemon" / "flight" / "context.py"
MUTATORS = frozenset(("append", "appendleft", "extend", "insert", "pop", "popleft", "clear", "add", "discard",
                      "remove", "update", "sort", "reverse"))
READERS = frozenset(("list", "tuple", "len", "bool", "sorted", "set", "dict", "any", "all", "sum", "max", "min",
                     "iter", "str", "repr", "float", "int", "isinstance"))
MUTABLE = ("list[", "set[", "dict[", "collections.deque[")
_WRITERS = re.compile(r"Writers?: ([\w, ]+?)(?:\.|;|$)", re.M)


class Field:
    def __init__(self, annotation: str, doc: str):
        m = _WRITERS.search(doc)
        self.writers = None if m is None else {w.strip() for w in m.group(1).split(",")}
        self.shared = "shared:" in doc
        self.mutable = annotation.startswith(MUTABLE)


def declared_fields(source: str) -> dict[str, Field]:
    """Dotted path of every field of ``FlightContext`` (its dataclass groups opened) -> its declaration."""
    classes = {n.name: n for n in ast.parse(source).body if isinstance(n, ast.ClassDef)}

    def fields(cls: ast.ClassDef, prefix: str) -> dict[str, Field]:
        found, body = {}, cls.body
        for i, node in enumerate(body):
            if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
                continue
            annotation = ast.unparse(node.annotation)
            if annotation in classes:                   # a group
                found.update(fields(classes[annotation], f"{prefix}{node.target.id}."))
                continue
            nxt = body[i + 1] if i + 1 < len(body) else None
            doc = nxt.value.value if isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant) else ""
            found[prefix + node.target.id] = Field(annotation, str(doc))
        return found
    return fields(classes["FlightContext"], "")


def _ctx_path(node: ast.AST) -> str | None:
    """``ctx.landing.requested`` (through any ``self.flight.ctx``...) -> ``landing.requested``; None
    when ``node`` is no attribute chain through a ``ctx``."""
    names = []
    while isinstance(node, ast.Attribute):
        names.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        names.append(node.id)
    names.reverse()
    if "ctx" not in names[:-1]:
        return None
    return ".".join(names[len(names) - names[::-1].index("ctx"):])


def context_writes(module: str, source: str) -> dict[str, set[str]]:
    """Field path -> {module} for every write of ``source`` to a context field."""
    writes: dict[str, set[str]] = {}

    def wrote(node: ast.AST) -> None:
        for target in (node.elts if isinstance(node, ast.Tuple) else [node]):
            if (path := _ctx_path(target)) is not None:
                writes.setdefault(path, set()).add(module)

    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Assign):
            for t in node.targets:
                wrote(t)
        elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
            wrote(node.target)
        elif isinstance(node, ast.Call):
            if isinstance(node.func, ast.Attribute) and node.func.attr in MUTATORS:
                wrote(node.func.value)
            if not (isinstance(node.func, ast.Name) and node.func.id in READERS):
                for arg in [*node.args, *(k.value for k in node.keywords)]:
                    if (path := _ctx_path(arg)) is not None:
                        writes.setdefault("(handed) " + path, set()).add(module)
    return writes


def ownership_findings(context_source: str, sources: dict[str, str]) -> list[str]:
    """What breaks the rule among ``sources`` (module name -> source) against the declarations of
    ``context_source``."""
    declared = declared_fields(context_source)
    found: dict[str, set[str]] = {}
    for module, source in sources.items():
        for path, modules in context_writes(module, source).items():
            handed = path.startswith("(handed) ")
            path = path.removeprefix("(handed) ")
            if handed and (path not in declared or not declared[path].mutable):
                continue                                # a value, or a group, read by a function
            found.setdefault(path, set()).update(modules)
    problems = [f"{p}: written by {sorted(m)}, not a field of FlightContext" for p, m in sorted(found.items())
                if p and p not in declared]
    for path, f in sorted(declared.items()):
        if f.writers is None:
            problems.append(f"{path}: its docstring names no writer")
            continue
        writers = found.get(path, set())
        if writers - f.writers:
            problems.append(f"{path}: written by {sorted(writers - f.writers)}, not declared")
        if f.writers - writers:
            problems.append(f"{path}: declared writer {sorted(f.writers - writers)} writes it nowhere")
        if len(f.writers) > 1 and not f.shared:
            problems.append(f"{path}: {len(f.writers)} writers and no reason it is shared")
    return problems


def _daemon_sources() -> dict[str, str]:
    root = ROOT / "mavreg" / "daemon"
    flight = root / "flight"
    return {(p.stem if p.parent == flight else p.relative_to(root).with_suffix("").as_posix()): p.read_text()
            for p in sorted(root.rglob("*.py")) if p != CONTEXT}


def test_every_field_of_the_flight_context_is_written_by_its_declared_owners():
    assert declared_fields(CONTEXT.read_text()).keys() >= {"phase", "s_m", "heard.last_sample", "landing.descent"}
    assert ownership_findings(CONTEXT.read_text(), _daemon_sources()) == []


def test_the_check_sees_a_new_writer_a_writer_gone_and_an_unexplained_share():
    context, sources = CONTEXT.read_text(), _daemon_sources()
    newcomer = "def f(flight):\n    flight.ctx.phase = None\n    flight.ctx.landing.descent.clear()\n"
    assert ownership_findings(context, {**sources, "newcomer": newcomer}) == [
        "landing.descent: written by ['newcomer'], not declared", "phase: written by ['newcomer'], not declared"]
    handed = "def f(ctx):\n    g(ctx.landing.descent, ctx.ground_z_m)\n    len(ctx.pending)\n"
    assert ownership_findings(context, {**sources, "newcomer": handed}) == [
        "landing.descent: written by ['newcomer'], not declared"]
    gone = {**sources, "status": sources["status"] + "\n\ndef f(ctx):\n    ctx.heard.foo = 1\n"}
    assert ownership_findings(context, gone) == ["heard.foo: written by ['status'], not a field of FlightContext"]
    unexplained = context.replace("Writers: hover_phases, verbs; shared: the hold ends it",
                                  "Writers: hover_phases, verbs. The hold ends it")
    assert ownership_findings(unexplained, sources) == ["excitation.end_vehicle_s: 2 writers and no reason it is shared"]
    moved = context.replace('"""When it came (injected clock). Writer: supervisor."""',
                            '"""When it came (injected clock). Writer: inbox."""')
    assert ownership_findings(moved, sources) == [
        "heard.last_sample_wall_s: written by ['supervisor'], not declared",
        "heard.last_sample_wall_s: declared writer ['inbox'] writes it nowhere"]
