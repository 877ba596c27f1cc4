"""Import rules: engine/ imports no Qt, pyqtgraph or viser; the layers of ARCHITECTURE.md hold
(import-linter contracts in pyproject.toml); no module takes part in an import cycle."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_import_linter_contracts_hold() -> None:
    exe = shutil.which("lint-imports") or str(Path(sys.executable).with_name("lint-imports"))
    proc = subprocess.run(
        [exe, "--config", str(ROOT / "pyproject.toml")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


#: import cycles known and being removed (each entry: the sorted modules of one cycle); empty
#: now: app.main <-> app.main_window, engine.sources <-> engine.sources.beacons and
#: engine.dense.tracking <-> engine.trackers.dense are gone
ALLOWED_CYCLES: set[tuple[str, ...]] = set()


def import_cycles(*packages: str) -> list[tuple[str, ...]]:
    """Strongly connected groups of more than one module (Tarjan) in the import graph of
    ``packages``: every import counts, also inside functions and under TYPE_CHECKING."""
    import grimp

    graph = grimp.build_graph(*packages, cache_dir=None)
    modules = sorted(graph.modules)
    edges = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[tuple[str, ...]] = []

    def visit(root: str) -> None:  # iterative: no recursion limit on long chains
        work = [(root, iter(edges[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(edges[w])))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    group = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        group.append(w)
                        if w == v:
                            break
                    if len(group) > 1:
                        groups.append(tuple(sorted(group)))

    for m in modules:
        if m not in index:
            visit(m)
    return sorted(groups)


def test_cycle_finder_finds_a_cycle(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    pkg = tmp_path / "cyc"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from cyc import b\n")
    (pkg / "b.py").write_text("def f():\n    from cyc import c\n")
    (pkg / "c.py").write_text("import cyc.a\n")
    (pkg / "d.py").write_text("import cyc.a\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert import_cycles("cyc") == [("cyc.a", "cyc.b", "cyc.c")]


def test_no_import_cycles() -> None:
    cycles = set(import_cycles("engine", "widgets", "app"))
    assert cycles - ALLOWED_CYCLES == set(), f"import cycles: {sorted(cycles - ALLOWED_CYCLES)}"
    assert ALLOWED_CYCLES - cycles == set(), "a cycle is gone: remove it from ALLOWED_CYCLES"


def test_engine_source_has_no_qt_import_statements() -> None:
    offenders = []
    for path in (ROOT / "engine").rglob("*.py"):
        for line in path.read_text(encoding="utf-8").splitlines():
            s = line.strip()
            if s.startswith(("import ", "from ")) and any(
                m in s.split()[1] for m in ("PySide6", "pyqtgraph", "viser", "shiboken6")
            ):
                offenders.append(f"{path.relative_to(ROOT)}: {s}")
    assert not offenders, offenders


def test_every_top_level_engine_module_has_a_layer() -> None:
    """import-linter checks only the modules its layers name: a new top-level module of
    engine/ must get a place in the "engine layers" contract of pyproject.toml."""
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    contract = next(c for c in config["tool"]["importlinter"]["contracts"]
                    if c.get("containers") == ["engine"] and c["type"] == "layers")
    placed = {name.strip(" ()") for layer in contract["layers"] for name in layer.split(":")}
    present = {p.stem if p.is_file() else p.name for p in (ROOT / "engine").iterdir()
               if (p.suffix == ".py" and p.stem != "__init__")
               or (p.is_dir() and (p / "__init__.py").exists())}
    assert present - placed == set(), (
        f"engine modules with no layer in pyproject.toml: {sorted(present - placed)}")
