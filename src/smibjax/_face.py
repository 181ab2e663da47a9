"""Lazy public faces (PEP 562): a package's public names, each loaded from its defining
module on first use, so that importing the package imports neither JAX nor equinox.

A face lists its names once, as `from .module import name as name` lines inside an
`if TYPE_CHECKING:` block (for type checkers and documentation tools), and calls
`lazy_face` with its own `__file__` and `__name__`. Standard library only.
"""

from __future__ import annotations

import ast
import importlib
from collections.abc import Callable
from pathlib import Path

__all__ = ["lazy_face"]


def lazy_face(
    init_file: str, package: str, submodules: tuple[str, ...] = ()
) -> tuple[dict[str, str], Callable[[str], object], Callable[[], list[str]]]:
    """(exports, __getattr__, __dir__) of the package `package` whose `__init__.py` is
    `init_file`: `exports` maps each public name to its defining module (read from the
    file's first `if` block); `__getattr__` loads a name on first use (and the
    `submodules` named, as modules); `__dir__` lists the loaded and the public names."""
    tree = ast.parse(Path(init_file).read_text(encoding="utf-8"))
    block = next(n for n in tree.body if isinstance(n, ast.If))
    exports = {a.asname: n.module for n in block.body for a in n.names}
    namespace = importlib.import_module(package).__dict__

    def getattr_(name: str):
        if name in exports:
            module = importlib.import_module(f".{exports[name]}", package)
            value = getattr(module, name)
            namespace[name] = value
            return value
        if name in submodules:
            return importlib.import_module(f".{name}", package)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def dir_() -> list[str]:
        return sorted([*namespace, *exports])

    return exports, getattr_, dir_
