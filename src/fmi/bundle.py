"""A Python FMU's ``resources/`` as a bundle that imports only itself.

An FMU's Python code runs in its host's one interpreter, with the host's one
``sys.modules``. Imported under their own top-level names (``glider_plant``,
``pythonfmu``, ...) the bundled packages would be shared with the host and with every
other FMU: the first copy imported wins. So the runtime imports each FMU's
``resources/`` as a package of its own, named after the SHA-256 of the code it holds
(``_glider_fmu_<hash>``, see ``bundle_loader.h``), and every import of a bundled name in
the bundled code is made relative at build time (:func:`relativize_bundle`): the
bundled ``from glider_plant.model import f`` becomes ``from ..glider_plant.model import
f``. Nothing is put on ``sys.path``; a name the bundle does not hold (the standard
library, a third-party package) is imported as usual.

The sources of the packages stay absolute (they are also installed as top-level
packages, where relative imports across them are impossible); only the bundled copies
are rewritten. Both spellings bind the same names, so the code runs the same.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import PurePosixPath

__all__ = ["BundleImportError", "bundle_names", "relativize", "relativize_bundle"]

#: prefix of the package name the runtime gives each bundle (the rest is its code's hash)
PACKAGE_PREFIX = "_glider_fmu_"


class BundleImportError(ValueError):
    """A bundled module's import cannot be made relative (names the file, line and form)."""


def bundle_names(paths: Iterable[str]) -> set[str]:
    """The top-level names a bundle holds, from its files' paths relative to ``resources/``.

    A ``.py`` file at the top is a module; a folder with an ``__init__.py`` a package.
    """
    names = set()
    for p in paths:
        parts = PurePosixPath(p).parts
        if len(parts) == 1 and parts[0].endswith(".py"):
            names.add(parts[0][:-3])
        elif len(parts) == 2 and parts[1] == "__init__.py":
            names.add(parts[0])
    return names


def _rewrite(node: ast.Import | ast.ImportFrom, names: set[str], dots: str) -> str | None:
    """The relative spelling of one import statement, or None if it imports no bundled name."""
    if isinstance(node, ast.ImportFrom):
        if node.level or not node.module or node.module.partition(".")[0] not in names:
            return None
        items = ", ".join(a.name + (f" as {a.asname}" if a.asname else "") for a in node.names)
        return f"from {dots}{node.module} import {items}"
    if not any(a.name.partition(".")[0] in names for a in node.names):
        return None
    out = []
    for a in node.names:
        top, _, rest = a.name.rpartition(".")
        if a.name.partition(".")[0] not in names:
            out.append(f"import {a.name}" + (f" as {a.asname}" if a.asname else ""))
        elif not top:  # import pkg [as x]
            out.append(f"from {dots} import {a.name}" + (f" as {a.asname}" if a.asname else ""))
        elif a.asname:  # import pkg.mod as x
            out.append(f"from {dots}{top} import {rest} as {a.asname}")
        else:  # import pkg.mod binds pkg: no relative spelling binds the same name
            raise BundleImportError(
                f"line {node.lineno}: 'import {a.name}' cannot be made relative: write "
                f"'from {top} import {rest}' or 'import {a.name} as NAME'"
            )
    return "; ".join(out)


def relativize(source: str, names: set[str], level: int, filename: str = "<bundle>") -> str:
    """``source`` with every absolute import of a bundled name made relative.

    Parameters
    ----------
    source : str
        A module's text.
    names : set of str
        The bundle's top-level names (:func:`bundle_names`).
    level : int
        How deep the module sits below ``resources/``: 1 for ``resources/X.py``, 2 for
        ``resources/pkg/mod.py`` and ``resources/pkg/__init__.py``.
    filename : str
        For messages.

    Raises
    ------
    BundleImportError
        ``source`` is not valid Python, or holds ``import pkg.mod`` of a bundled package
        (it binds ``pkg``, which no relative import can).
    """
    try:
        tree = ast.parse(source, filename)
    except SyntaxError as err:
        raise BundleImportError(f"{filename}: line {err.lineno}: {err.msg}") from None
    edits = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            try:
                text = _rewrite(node, names, "." * level)
            except BundleImportError as err:
                raise BundleImportError(f"{filename}: {err}") from None
            if text is not None:
                end = (node.end_lineno or node.lineno, node.end_col_offset or 0)
                edits.append((node.lineno, node.col_offset, *end, text))
    if not edits:
        return source
    data = source.encode()
    offsets = [0]  # bytes.splitlines breaks lines where the parser does (\n, \r\n, \r)
    for line in data.splitlines(keepends=True):
        offsets.append(offsets[-1] + len(line))
    for l0, c0, l1, c1, text in sorted(edits, reverse=True):
        start, end = offsets[l0 - 1] + c0, offsets[l1 - 1] + c1  # ast offsets are in bytes
        data = data[:start] + text.encode() + data[end:]
    return data.decode()


def relativize_bundle(files: dict[str, bytes]) -> dict[str, bytes]:
    """Every ``.py`` file of a bundle (paths relative to ``resources/`` -> bytes), relativized.

    Files that are not Python, and modules with no bundled import, come back unchanged.
    """
    names = bundle_names(files)
    out = {}
    for path, data in files.items():
        if path.endswith(".py"):
            level = len(PurePosixPath(path).parts)
            data = relativize(data.decode(), names, level, f"resources/{path}").encode()
        out[path] = data
    return out
