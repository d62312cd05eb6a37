# SPDX-License-Identifier: GPL-3.0-or-later
"""The shipped add-on never imports what the extension zip leaves out: ``validation/`` (the references and the
accuracy bench), ``tools/`` and ``tests/``, nor the reference modules that once lived in ``atmos_addon.physics``.

Every ``.py`` under ``atmos_addon/``, ``node_groups/`` and ``sample_scenes/`` is parsed (imports at module level and
inside functions alike) and each import resolved to its full dotted name: ``node_groups`` and ``sample_scenes`` are
imported as ``atmos_addon.node_groups`` and ``atmos_addon.sample_scenes`` (``atmos_addon.__path__`` holds the
extension root), so a relative ``..validation`` in them would reach the checkout's ``validation/`` through the add-on.
The installed zip importing every one of its modules without ``validation`` on the path is
``tests/blender/test_extension_package.py``'s.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
#: The source folders the extension zip ships.
SHIPPED = ("atmos_addon", "node_groups", "sample_scenes")
#: Top-level folders the zip excludes (``paths_exclude_pattern`` in blender_manifest.toml).
EXCLUDED = ("validation", "tools", "tests")
#: Modules moved from ``atmos_addon.physics`` to ``validation``: a stale import of one would fail installed only.
MOVED = ("reference", "multiple_scattering_reference", "spectral_reference", "balanced")


def sources() -> list[Path]:
    return sorted(path for folder in SHIPPED for path in (REPO_ROOT / folder).rglob("*.py")
                  if "__pycache__" not in path.parts)


def package_of(path: Path) -> list[str]:
    """The package a file's relative imports resolve against, as its dotted parts."""
    parts = list(path.relative_to(REPO_ROOT).with_suffix("").parts)
    if parts[0] != "atmos_addon":
        parts.insert(0, "atmos_addon")
    parts.pop()   # a module resolves against its package; a package's __init__ against the package itself
    return parts


def imported(path: Path) -> Iterator[tuple[int, str]]:
    """(line, full dotted name) of every module and name ``path`` imports, ``importlib.import_module`` of a
    constant string included."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            yield from ((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package_of(path)
                base = base[:len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            yield node.lineno, module
            yield from ((node.lineno, f"{module}.{alias.name}") for alias in node.names)
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None))
              in ("import_module", "__import__") and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)):
            yield node.lineno, node.args[0].value


def forbidden(name: str) -> bool:
    """Whether ``name`` is in (or is) an excluded package or a moved module, directly or through ``atmos_addon``."""
    bare = name.removeprefix("atmos_addon.")
    prefixes = EXCLUDED + tuple(f"physics.{module}" for module in MOVED)
    return any(bare == prefix or bare.startswith(prefix + ".") for prefix in prefixes)


def test_the_walk_sees_every_shipped_folder_and_resolves_relative_imports() -> None:
    files = sources()
    for folder in SHIPPED:
        assert any(path.relative_to(REPO_ROOT).parts[0] == folder for path in files), folder
    # The resolution the check relies on, on imports the add-on has: relative from a subpackage, from a
    # package's __init__ and from node_groups (a subpackage of atmos_addon by its __path__).
    names = {name for path in files for _, name in imported(path)}
    assert "atmos_addon.physics.quality.choose_level" in names          # blender/quality_choice.py: ..physics.quality
    assert "atmos_addon.physics.sky" in names                           # physics/__init__.py: from . import sky
    assert any(name.startswith("atmos_addon.node_groups.") for name in names)
    assert forbidden("validation.accuracy") and forbidden("atmos_addon.validation") and forbidden("tools.bench")
    assert forbidden("atmos_addon.physics.reference.single_scattering") and not forbidden("atmos_addon.physics.quality")


def test_no_shipped_module_imports_what_the_zip_leaves_out() -> None:
    bad = [f"{path.relative_to(REPO_ROOT)}:{line}: {name}" for path in sources() for line, name in imported(path)
           if forbidden(name)]
    assert not bad, "the add-on imports what the extension does not ship:\n" + "\n".join(bad)
