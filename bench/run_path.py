"""The path of one run through glider_cosim's folders: how many it passes through and
how often it turns back (issue 55, "layers that the imports show").

The default scenario runs through the library, ``glider_cosim.runner.run.simulate(None,
out=<temp folder>, plots=False)``, once to warm the FMU cache (unprofiled), then once
under :func:`sys.setprofile` (main thread; the run starts no other thread of ours).

What is counted, precisely:

- **folder** of a Python function: the sub-folder of the ``glider_cosim`` package its
  file is in (``runner``, ``master``, ``fmus``, ...; a top-level module such as
  ``progress.py`` is ``"."``). Functions outside the package (the standard library,
  fmpy, numpy, the other four import packages, the FMUs' bundled copies) are not ours:
  they are transparent, their time counts to the innermost function of ours that
  called them.
- **calls**: Python function calls (generator resumptions too) into our package.
- **where the run is**, at each moment: the folder of the innermost frame of our package
  on the call stack (kept as a stack of our frames: pushed on their call, popped on
  their return or exception).
- **stop**: a stretch of the run during which that folder stays the same; a new stop
  begins each time it changes. **stops** counts them, **folders** is the number of
  distinct folders among them (listed on the ``visited`` line).
- **climbs back up**: a stop entered by a return: a function of ours returns (or
  raises) and the innermost frame of ours left, its caller's (possibly through other
  code), is in another folder. A call down that comes back is one climb; a layered
  path climbs once per call down.
- **returns to a folder already left**: a stop in a folder that an earlier stop, other
  than the immediately previous one, was in (consecutive stops differ, so: any earlier
  stop). Entered by a call or by a return.
- **calls up the layers**: a stop entered by a call into a folder that is on a higher
  layer than the caller's (``tests/test_layout.py``'s ``LAYERS``, read from
  docs/explanation/code-layout.md's diagram of the measured tree): a callback.
- The loop repeats per macro step whatever crosses folders per step, so the counts
  scale with the run's length; **distinct moves** counts the distinct ``(from, to, by
  call or return)`` pairs among the stops, whatever their number, and ``moves`` lists
  them.

``--rev COMMIT`` measures another commit: a ``git worktree`` of it in a temporary
folder, its five import packages linked under their import names as
``pyproject.toml``'s ``package-dir`` maps them, and this script run there with that
folder first on ``PYTHONPATH`` (same interpreter, same FMU cache: the warm-up run
builds the FMUs for the commit's sources if the cache lacks them).

``--trace`` prints each stop (how it was entered, its folder, the function of ours it
began in) on stderr.

Usage: python bench/run_path.py [--rev COMMIT] [--trace] [--json]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import tomllib
from collections import Counter
from pathlib import Path

from _common import emit

HERE = Path(__file__).resolve().parent


def folder_of(package_dir: str):
    """A function ``co_filename -> folder`` (None: not our package), cached."""
    prefix = package_dir + os.sep
    cache: dict[str, str | None] = {}

    def folder(filename: str) -> str | None:
        try:
            return cache[filename]
        except KeyError:
            pass
        real = os.path.realpath(filename)
        result = None
        if real.startswith(prefix):
            parts = real[len(prefix) :].split(os.sep)
            result = "." if len(parts) == 1 else parts[0]
        cache[filename] = result
        return result

    return folder


def layers_of(package_dir: Path) -> dict[str, int]:
    """folder -> layer, from the diagram of docs/explanation/code-layout.md (``"."``:
    the lowest of the top-level modules' layers); empty without the doc."""
    doc = package_dir.parent / "docs" / "explanation" / "code-layout.md"
    if not doc.is_file():
        return {}
    text = doc.read_text()
    start = text.find("```\nlayer")
    if start < 0:
        return {}
    block = text[start + 4 : text.index("\n```", start + 4)]
    layer: dict[str, int] = {}
    for line in block.splitlines()[1:]:
        words = line.split()
        if len(words) >= 2 and words[0].isdigit() and words[1].startswith("glider_cosim."):
            name = words[1].removeprefix("glider_cosim.")
            if (package_dir / name).is_dir():
                layer[name] = int(words[0])
            else:
                layer["."] = min(layer.get(".", 99), int(words[0]))
    return layer


def measure(trace: bool = False) -> dict[str, object]:
    """Run the default scenario twice (warm-up, then profiled): the figures (``trace``:
    each stop on stderr, with the function of ours it began in)."""
    import glider_cosim
    from glider_cosim.runner.run import simulate

    package_dir = Path(os.path.realpath(glider_cosim.__file__)).parent
    folder = folder_of(str(package_dir))
    with tempfile.TemporaryDirectory(prefix="glider-bench-path-") as tmp:
        simulate(None, out=Path(tmp) / "warm", plots=False)
        stack: list[str] = []
        stops: list[tuple[str, str]] = []  # (folder, "call" | "return")
        where: list[str] = []  # per stop: the function of ours it began in
        names: list[str] = []  # the stack's functions
        calls = 0

        def profile(frame, event, arg):  # noqa: ARG001 (sys.setprofile's signature)
            nonlocal calls
            if event == "call":
                f = folder(frame.f_code.co_filename)
                if f is None:
                    return
                calls += 1
                stack.append(f)
                names.append(f"{frame.f_code.co_filename}:{frame.f_code.co_qualname}")
                if not stops or stops[-1][0] != f:
                    stops.append((f, "call"))
                    where.append(names[-1])
            elif event == "return":
                f = folder(frame.f_code.co_filename)
                if f is None or not stack:
                    return
                stack.pop()
                names.pop()
                if stack and stops[-1][0] != stack[-1]:
                    stops.append((stack[-1], "return"))
                    where.append(names[-1])

        out = Path(tmp) / "run"
        sys.setprofile(profile)
        try:
            result = simulate(None, out=out, plots=False)
        finally:
            sys.setprofile(None)
        rows = len(result.data)
    layer = layers_of(package_dir)
    seen: set[str] = set()
    revisits = climbs = up = 0
    moves: Counter[tuple[str, str, str]] = Counter()
    for i, (f, how) in enumerate(stops):
        if f in seen:
            revisits += 1
        seen.add(f)
        if i == 0:
            continue
        prev = stops[i - 1][0]
        moves[prev, f, how] += 1
        if how == "return":
            climbs += 1
        elif f in layer and prev in layer and layer[f] > layer[prev]:
            up += 1
    visited = sorted({f for f, _ in stops})
    if trace:
        for (f, how), name in zip(stops, where, strict=True):
            print(f"{how:6} {f:10} {os.path.relpath(name, package_dir)}", file=sys.stderr)
    return {
        "rows": rows,
        "calls": calls,
        "stops": len(stops),
        "folders": len(visited),
        "visited": " ".join(visited),
        "climbs_back_up": climbs,
        "returns_to_a_folder_already_left": revisits,
        "calls_up_the_layers": up,
        "distinct_moves": len(moves),
        "moves": ", ".join(
            f"{a}>{b}" + ("" if how == "call" else "(ret)") + f" x{n}"
            for (a, b, how), n in sorted(moves.items())
        ),
    }


def at_rev(rev: str, flags: list[str]) -> None:
    """This script run on a worktree of ``rev`` (see the module's docstring)."""
    top = subprocess.run(
        ["git", "rev-parse", "--show-toplevel"], cwd=HERE, capture_output=True, text=True,
        check=True,
    ).stdout.strip()  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="glider-bench-rev-") as tmp:
        tree = Path(tmp) / "tree"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(tree), rev],
                       cwd=top, check=True)  # fmt: skip
        try:
            pyproject = tomllib.loads((tree / "pyproject.toml").read_text())
            links = Path(tmp) / "packages"
            links.mkdir()
            for name, sub in pyproject["tool"]["setuptools"]["package-dir"].items():
                (links / name).symlink_to(tree / sub, target_is_directory=True)
            env = {**os.environ, "PYTHONPATH": os.pathsep.join(
                [str(links), *filter(None, [os.environ.get("PYTHONPATH")])])}  # fmt: skip
            cmd = [sys.executable, str(HERE / "run_path.py"), "--here", *flags]
            subprocess.run(cmd, env=env, check=True)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=top,
                           check=False)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", help="measure this commit (a git worktree of it)")
    ap.add_argument("--here", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--trace", action="store_true", help="each stop on stderr")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.rev and not args.here:
        at_rev(args.rev, [f for f in ("--json", "--trace") if getattr(args, f[2:])])
        return
    result = measure(args.trace)
    import glider_cosim

    result = {"package": str(Path(glider_cosim.__file__).parent), **result}
    emit(result, args.json)


if __name__ == "__main__":
    main()
