"""A plain fmpy script with our three FMUs exits normally, every time (no abort at exit).

pythonfmu's binary aborted about 1 such exit in 20 ("corrupted double-linked list"); our
runtime never finalizes an interpreter and holds exactly the references it takes. 30 runs
here (bench/exit_stress.py runs 500), half of them without terminate/free.
"""

from __future__ import annotations

import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration
SCRIPT = Path(__file__).parents[2] / "bench" / "plain_fmpy_script.py"


def test_plain_fmpy_script_exits_0_in_30_of_30_runs(fmu_dir):
    cmds = [[sys.executable, str(SCRIPT), str(fmu_dir), *(["--no-free"] if i % 2 else [])]
            for i in range(30)]  # fmt: skip

    def run(cmd):
        return subprocess.run(cmd, capture_output=True, text=True, timeout=300)

    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(run, cmds))
    failed = [(r.returncode, r.stderr[-500:]) for r in results if r.returncode != 0]
    assert not failed, failed


AT_EXIT_C = r"""
#include <stdio.h>
#include <stdlib.h>
typedef int (*Call)(void *);
typedef int (*Get)(void *, const unsigned *, size_t, double *);
typedef int (*Step)(void *, double, double, int);
typedef void (*Free)(void *);
static void *g_c;
static Call g_term;
static Get g_get;
static Step g_step;
static Free g_free;
void c_logger(void *env, const char *name, int status, const char *category,
              const char *message, ...) {
    (void)env; (void)name; (void)category;
    printf("logged %d %s\n", status, message);
}
/* after the interpreter has finalized: a tool ending its instances at process exit */
static void at_exit(void) {
    unsigned vr = 0;
    double v = 0.0;
    printf("get %d\n", g_get(g_c, &vr, 1, &v));
    printf("step %d\n", g_step(g_c, 0.0, 0.02, 1));
    printf("terminate %d\n", g_term(g_c));
    printf("terminate again %d\n", g_term(g_c));
    g_free(g_c);
    printf("freed\n");
    fflush(stdout);
}
void arm(void *c, void *term, void *get, void *step, void *free_) {
    g_c = c; g_term = (Call)term; g_get = (Get)get; g_step = (Step)step; g_free = (Free)free_;
    atexit(at_exit);
}
"""

AT_EXIT_SCRIPT = r"""
import ctypes, sys
sys.path.insert(0, {here!r})
from raw_fmi import RawFMU
from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackLoggerTYPE)
helper = ctypes.CDLL({helper!r})
libc = ctypes.CDLL(None)
raw = RawFMU({fmu!r})
addr = lambda f: ctypes.cast(f, ctypes.c_void_p).value
# C callbacks: nothing of Python's is called once it has finalized
raw.callbacks.logger = fmi2CallbackLoggerTYPE(addr(helper.c_logger))
raw.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(addr(libc.calloc))
raw.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(addr(libc.free))
c = raw.instantiate("late")
assert c and raw.initialize(c) == 0
assert raw.DoStep(c, 0.0, 0.02, 1) == 0
helper.arm(ctypes.c_void_p(c), *(ctypes.c_void_p(addr(getattr(raw.dll, f"fmi2{{n}}")))
                                 for n in ("Terminate", "GetReal", "DoStep", "FreeInstance")))
print("armed", flush=True)
"""


def test_calls_after_the_interpreter_finalized_follow_the_per_call_policy(fmu_dir, tmp_path):
    """The back end gone (the host's Python finalized) goes through begin(): fmi2Terminate
    of a stepping instance is OK, once; any other call is fmi2Error; FreeInstance frees;
    and nothing is logged (the host's logger may be Python's too)."""
    src = tmp_path / "at_exit.c"
    src.write_text(AT_EXIT_C)
    helper = tmp_path / "at_exit.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-Wall", "-Wextra", "-Werror", "-o", str(helper),
                    str(src)], check=True)  # fmt: skip
    script = AT_EXIT_SCRIPT.format(here=str(Path(__file__).parent), helper=str(helper),
                                   fmu=str(fmu_dir / "GliderController.fmu"))  # fmt: skip
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=120)  # fmt: skip
    assert p.returncode == 0, p.stderr[-1500:]
    assert p.stdout.splitlines() == [
        "armed", "get 3", "step 3", "terminate 0", "terminate again 3", "freed",
    ], p.stdout  # fmt: skip
