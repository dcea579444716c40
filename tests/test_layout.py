"""The test tree mirrors src/ (tests/README.md): every module has its test file, every unit test file its module.

- `src/tumble/<package>/<module>.py` is tested in `tests/unit/<package>/test_<module>.py`, and a
  module with several test files adds `test_<module>_<topic>.py` beside it; this holds for every
  module, the renderer's, the viewer's and the commands' included (no module is left to a
  cross-module suite alone);
- test files in folders without `__init__.py` are imported by their basename, so those basenames
  must be unique (pytest's default "prepend" import mode).
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "tumble"
TESTS = ROOT / "tests"
UNIT = TESTS / "unit"

#: unit test files that check the whole package rather than one module
PACKAGE_WIDE = {"test_cuda_codegen.py"}  # every Warp kernel compiles for CUDA


def modules() -> list[str]:
    """Every module of the package as "package/module" (or "module"), package __init__ and __main__ aside."""
    return sorted(
        p.relative_to(SRC).with_suffix("").as_posix()
        for p in SRC.rglob("*.py")
        if p.name not in ("__init__.py", "__main__.py")
    )


def test_every_module_has_its_test_file():
    """tests/unit/<package>/test_<module>.py exists for every module of src/tumble."""
    assert len(modules()) > 50, f"the modules of {SRC} were not found"
    missing = []
    for module in modules():
        path = UNIT.joinpath(module).parent / f"test_{Path(module).name}.py"
        if not path.is_file():
            missing.append(f"{module}: no {path.relative_to(ROOT)}")
    assert not missing, "\n".join(missing)


def test_every_unit_test_file_names_its_module():
    """tests/unit/<package>/test_<module>[_<topic>].py: <module> is a module of src/tumble/<package>."""
    known = set(modules())
    orphans = []
    for path in sorted(UNIT.rglob("test_*.py")):
        if path.name in PACKAGE_WIDE:
            continue
        package = path.parent.relative_to(UNIT).as_posix()
        stem = path.stem.removeprefix("test_")
        parts = stem.split("_")
        candidates = ["_".join(parts[:k]) for k in range(len(parts), 0, -1)]
        if not any((f"{package}/{c}" if package != "." else c) in known for c in candidates):
            orphans.append(path.relative_to(ROOT).as_posix())
    assert not orphans, f"unit test files without a module of that name: {orphans}"


def test_unit_test_packages_have_init_files():
    """Each folder under tests/unit is a package, so that basenames may repeat across folders."""
    missing = [
        p.relative_to(ROOT).as_posix()
        for p in [UNIT, *UNIT.rglob("*")]
        if p.is_dir() and p.name != "__pycache__" and not (p / "__init__.py").is_file()
    ]
    assert not missing, f"add __init__.py to {missing}"


def test_basenames_are_unique_where_they_are_imported_by_basename():
    """Test files in folders without __init__.py import as their basename: two of one name would clash."""
    seen: dict[str, list[str]] = {}
    for path in TESTS.rglob("test_*.py"):
        if not (path.parent / "__init__.py").is_file():
            seen.setdefault(path.name, []).append(path.relative_to(ROOT).as_posix())
    clashes = {name: paths for name, paths in seen.items() if len(paths) > 1}
    assert not clashes, f"rename one of each: {clashes}"


def _imports(path: Path, module: str, modules: set[str]) -> set[str]:
    """Tumble modules that `module` imports anywhere in its file (functions included), TYPE_CHECKING blocks aside."""
    import ast

    tree = ast.parse(path.read_text(encoding="utf-8"))
    typing_only = {
        id(sub)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING"
        for sub in ast.walk(node)
    }
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name in modules)
        elif isinstance(node, ast.ImportFrom):
            base = package
            for _ in range(node.level - 1):
                base = base.rpartition(".")[0]
            target = node.module if not node.level else (f"{base}.{node.module}" if node.module else base)
            for a in node.names:
                out.add(f"{target}.{a.name}" if f"{target}.{a.name}" in modules else target)
    return (out & modules) - {module}


def test_no_import_cycles():
    """No chain of imports, module-level or inside functions, leads from a module back to itself."""
    files = {}
    for path in SRC.rglob("*.py"):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph = {m: _imports(p, m, set(files)) for m, p in files.items()}
    # depth-first search for a back edge; the package itself (`tumble`) is the public front, imported by
    # commands, io and the viewer, and imports only world-side modules, so it takes part like any other
    state: dict[str, int] = {}
    path_now: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        path_now.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                raise AssertionError("import cycle: " + " -> ".join(path_now[path_now.index(n) :] + [n]))
            if n not in state:
                visit(n)
        path_now.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
