"""The project's footprint (issue 53): lines of Python, C and JavaScript outside the
tests, the number of required dependencies, and the size of a fresh venv after
``pip install .`` and after ``pip install '.[test]'``, for one checkout.

Usage::

    python bench/footprint.py [CHECKOUT ...] [--json] [--no-venv]

CHECKOUT is a project folder (default: this one). Lines are counted in the files git
tracks (every file but the build outputs where it is not a git work tree) outside
``tests/``, blank lines included; the required dependencies are
``[project] dependencies`` of its pyproject.toml; each venv is made in a temporary
folder with the Python running this script and removed after it is measured (its
files' sizes added up, symlinks not followed). Two venvs take minutes: ``--no-venv``
leaves them out.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

#: the languages counted, by file suffix
LANGUAGES = {".py": "python", ".c": "c", ".h": "c", ".js": "javascript"}
#: where the checkout is not a git work tree: top-level folders not counted (the tests,
#: outputs and builds), and folders not counted anywhere
SKIPPED_TOP = {"tests", "out", "fmus", "build", "dist", ".venv"}
SKIPPED = {".git", "__pycache__", "_build"}


def source_files(checkout: Path) -> list[Path]:
    """The checkout's files outside ``tests/``: git's tracked ones, else a walk that
    skips :data:`SKIPPED_TOP` and :data:`SKIPPED`."""
    proc = subprocess.run(["git", "-C", str(checkout), "ls-files", "-z"], capture_output=True,
                          check=False)  # fmt: skip
    if proc.returncode == 0 and proc.stdout:
        names = [n for n in proc.stdout.decode().split("\0") if n]
        return [checkout / n for n in names if not n.startswith("tests/")]
    found = []
    for folder, dirs, files in os.walk(checkout):
        top = Path(folder) == checkout
        dirs[:] = [d for d in dirs if d not in SKIPPED and not d.endswith(".egg-info")
                   and not (top and d in SKIPPED_TOP)]  # fmt: skip
        found += [Path(folder) / f for f in files]
    return found


def line_counts(checkout: Path) -> dict[str, int]:
    """Lines per language (:data:`LANGUAGES`) outside ``tests/``."""
    counts = dict.fromkeys(sorted(set(LANGUAGES.values())), 0)
    for path in source_files(checkout):
        language = LANGUAGES.get(path.suffix)
        if language and path.is_file():
            with open(path, "rb") as f:
                counts[language] += sum(1 for _ in f)
    return counts


def required(checkout: Path) -> list[str]:
    """``[project] dependencies`` of the checkout's pyproject.toml."""
    return tomllib.loads((checkout / "pyproject.toml").read_text())["project"]["dependencies"]


def folder_size(folder: Path) -> int:
    """Bytes of every file under ``folder`` (symlinks not followed)."""
    total = 0
    for root, _, files in os.walk(folder):
        for name in files:
            path = os.path.join(root, name)
            if not os.path.islink(path):
                total += os.stat(path).st_size
    return total


def venv_size(checkout: Path, target: str) -> int:
    """Bytes of a fresh venv after ``pip install TARGET`` (``.`` or ``.[test]``, relative
    to ``checkout``)."""
    with tempfile.TemporaryDirectory(prefix="footprint-") as tmp:
        venv = Path(tmp) / "venv"
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        pip = [str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet",
               "--disable-pip-version-check"]  # fmt: skip
        subprocess.run([*pip, target.replace(".", str(checkout), 1)], check=True,
                       stdout=subprocess.DEVNULL)  # fmt: skip
        return folder_size(venv)


def footprint(checkout: Path, venvs: bool = True) -> dict[str, object]:
    """The checkout's figures: lines per language, required dependencies and, with
    ``venvs``, the two venv sizes (bytes)."""
    checkout = checkout.resolve()
    out: dict[str, object] = {"checkout": str(checkout)}
    lines = line_counts(checkout)
    out.update({f"{k}_lines": v for k, v in lines.items()})
    deps = required(checkout)
    out["required_dependencies"] = len(deps)
    out["required"] = deps
    if venvs:
        out["venv_bytes"] = venv_size(checkout, ".")
        out["venv_test_bytes"] = venv_size(checkout, ".[test]")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkout", nargs="*", type=Path,
                        default=[Path(__file__).resolve().parents[1]])  # fmt: skip
    parser.add_argument("--json", action="store_true", help="one JSON object per checkout")
    parser.add_argument("--no-venv", action="store_true", help="leave the venv sizes out")
    args = parser.parse_args(argv)
    for checkout in args.checkout:
        if not (checkout / "pyproject.toml").is_file():
            sys.stderr.write(f"{checkout}: no pyproject.toml: expected a project folder\n")
            return 2
    for checkout in args.checkout:
        found = footprint(checkout, venvs=not args.no_venv)
        if args.json:
            print(json.dumps(found))
            continue
        print(f"{found['checkout']}:")
        for key in ("python_lines", "c_lines", "javascript_lines", "required_dependencies"):
            print(f"  {key}: {found[key]}")
        for key in ("venv_bytes", "venv_test_bytes"):
            if key in found:
                print(f"  {key}: {found[key]} ({found[key] / 1e6:.0f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
