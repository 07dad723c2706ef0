"""``glider-cosim build-onboard``: the native controller as a standalone UDP endpoint.

The program is the controller's own C files (its model, the generated variable table,
``GLIDER_NATIVE_MODEL``) with ``onboard_main.c`` (the message format of
:mod:`.protocol`, no FMI layer), compiled by the project's zig (:mod:`glider_fmi.toolchain`)
into a program for ``x86_64-linux`` or ``aarch64-linux`` (glibc 2.17 or later, as the
native FMUs: the same libm, hence the same bits) or ``x86_64-windows`` (an .exe).
"""

from __future__ import annotations

import platform
import shutil
import subprocess
import tempfile
from pathlib import Path

from glider_fmi import toolchain

from ..components import component as registry_component
from ..fmus.native import CFLAGS, FMI_DIR, NATIVE_COMPONENTS, vars_header

#: the ``--target`` values: the native FMUs' platforms (zig's target, glibc 2.17 on
#: Linux: the same C library, so the same libm and the same bits, as the FMU's binary)
TARGETS = ("x86_64-linux", "aarch64-linux", "x86_64-windows")
MAIN = Path(__file__).resolve().parent / "onboard_main.c"


class OnboardBuildError(ValueError):
    """The onboard program cannot be built (a bad target, no zig, a compiler error)."""


def host_target() -> str:
    """This machine's ``--target``."""
    return "aarch64-linux" if platform.machine() in ("aarch64", "arm64") else "x86_64-linux"


def build_onboard(out: Path, target: str | None = None, component: str = "controller") -> Path:
    """Build the onboard program of ``component`` for ``target`` (default: this machine)
    into the folder ``out``; returns the program's path.

    Raises
    ------
    OnboardBuildError
        An unknown target, zig missing, or the compiler failed or warned.
    """
    target = target or host_target()
    if target not in TARGETS:
        raise OnboardBuildError(
            f"--target {target!r} is unknown: expected one of {', '.join(TARGETS)}"
        )
    if component != "controller":
        raise OnboardBuildError(f"{component!r}: only the controller is built onboard")
    if not toolchain.zig_available():
        raise OnboardBuildError("zig is missing: pip install ziglang")
    model = registry_component(component).model
    c = next(c for c in NATIVE_COMPONENTS if c.name == model)
    name = "glider-controller-onboard" + (".exe" if "windows" in target else "")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="glider-onboard-") as tmp:
        stage = Path(tmp)
        for f in (*c.files, FMI_DIR / "native_model.h", FMI_DIR / "glider_fp.h", MAIN):
            shutil.copy(f, stage / f.name)
        (stage / f"{c.name}_vars.h").write_text(vars_header(c))
        sources = sorted(str(p) for p in stage.glob("*.c"))
        _say_zig_first(target)
        libs = ["-lws2_32"] if "windows" in target else ["-lm"]
        cmd = [*toolchain.zig_command(), "-target",
               toolchain.PLATFORMS[target].zig_target, *CFLAGS,
               "-D_POSIX_C_SOURCE=200112L", f"-I{stage}", *sources, "-o",
               str(stage / name), *libs]  # fmt: skip
        p = subprocess.run(cmd, capture_output=True, text=True)  # no time limit: slow is not failed
        if p.returncode != 0 or p.stderr.strip():
            first = " ".join((p.stderr or p.stdout).split())[:400]
            raise OnboardBuildError(f"build-onboard ({target}): the compiler says: {first}")
        shutil.copy(stage / name, out / name)
    return out / name


def _say_zig_first(target: str) -> None:
    """zig's one-time build of ``target``'s C runtime into its cache, named if it is to come
    (:func:`glider_cosim.fmus.objects.zig_first_note`): the only long wait of this build."""
    from ..fmus.objects import Target, zig_first_note
    from ..progress import say

    zig = toolchain.select("zig").for_platform(target)
    note = zig_first_note(Target(target, toolchain.PLATFORMS[target], zig)) if zig else None
    if note:
        say(f"build-onboard: {note}")
