"""Everything our FMUs and the one-FMU export's forwarder pass to a logger follows FMI's
'#' rule (FMI 2.0 section 2.1.5; FMI 3.0 the same with ``#<vr>#``), read as FMI Library
reads it (:mod:`fmi_log_rule`).

Each of the 12 FMUs (3 components, both flavors, FMI 2.0 and 3.0) runs under an
instance name with a ``#`` in it, every log category on: info lines of every call, the
observer's warning for a step that does not match its sample rate, an error for a NaN
input and one for a NaN parameter. The forwarder's rewriting runs in a C harness under
AddressSanitizer; the export itself in ``test_onefmu.py``.
"""

from __future__ import annotations

import ctypes
import subprocess
import sys
from ctypes import c_bool, c_char_p, c_double, c_uint
from pathlib import Path

import pytest
from system_tools import require_tool

sys.path.insert(0, str(Path(__file__).parent))
from fmi3_fuzz import Raw3  # noqa: E402
from fmi_log_rule import FmiMessageError, parse_fmi_message  # noqa: E402
from raw_fmi import RawFMU  # noqa: E402

pytestmark = pytest.mark.integration
NAME = "glider#1"
NAMES = ("GliderPlant", "GliderObserver", "GliderController")


def test_the_parser_reads_as_fmi_library():
    assert parse_fmi_message("a ## b #r12# c", 2) == ("a # b {ref} c", ["#r12#"])
    assert parse_fmi_message("#7# and ##", 3) == ("{ref} and #", ["#7#"])
    for bad, fmi in (("FMU#0: x", 2), ("line #3", 2), ("#r12", 2), ("# x", 3), ("#r1#", 3)):
        with pytest.raises(FmiMessageError, match="neither '##' nor a reference"):
            parse_fmi_message(bad, fmi)


def _fmi2_messages(fmu: Path) -> list[str]:
    raw = RawFMU(fmu)
    cats = (c_char_p * len(raw.md.logCategories))(*(c.name.encode() for c in raw.md.logCategories))
    inputs = [v.name for v in raw.md.modelVariables if v.causality == "input" and v.type == "Real"]
    param = next(v.name for v in raw.md.modelVariables if v.causality == "parameter"
                 and v.type == "Real")  # fmt: skip
    c = raw.instantiate(NAME, logging=True)
    raw.SetDebugLogging(c, 1, len(cats), cats)
    assert raw.initialize(c) == 0
    raw.DoStep(c, 0.0, 0.05, 1)  # the observer warns: 1/step is not f_sample
    raw.set_real(c, **{inputs[0]: float("nan")})
    assert raw.DoStep(c, 0.05, 0.05, 1) >= 3  # a NaN input: an error
    raw.FreeInstance(c)
    c = raw.instantiate(NAME, logging=True)
    raw.set_real(c, **{param: float("nan")})
    assert raw.initialize(c) >= 3  # a NaN parameter: an error
    raw.FreeInstance(c)
    return [m.text.replace("%", "%%") for m in raw.messages]  # as the FMU wrote it


def _fmi3_messages(fmu: Path) -> list[str]:
    raw = Raw3(fmu)
    md = raw.md
    cats = (c_char_p * len(md.logCategories))(*(c.name.encode() for c in md.logCategories))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    inputs = [v.name for v in md.modelVariables if v.causality == "input" and v.type == "Float64"]
    param = next(v.name for v in md.modelVariables if v.causality == "parameter"
                 and v.type == "Float64")  # fmt: skip
    flags = [c_bool() for _ in range(3)]
    last = c_double()

    def step(c, t):
        return raw.DoStep(c, t, 0.05, True, *(ctypes.byref(f) for f in flags), ctypes.byref(last))

    def set_nan(c, name):
        return raw.SetFloat64(c, (c_uint * 1)(vr[name]), 1, (c_double * 1)(float("nan")), 1)

    c = raw.instantiate(NAME, logging=True)
    raw.SetDebugLogging(c, True, len(cats), cats)
    assert raw.initialize(c) == 0
    step(c, 0.0)
    set_nan(c, inputs[0])
    assert step(c, 0.05) >= 3
    raw.FreeInstance(c)
    c = raw.instantiate(NAME, logging=True)
    set_nan(c, param)
    assert raw.initialize(c) >= 3
    raw.FreeInstance(c)
    return [m.decode() for _, m in raw.messages]


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("flavor", ["python", "native"])
@pytest.mark.parametrize("name", NAMES)
def test_every_message_of_our_fmus_follows_the_rule(fmu_dir, native_dir, fmi3_dirs, fmi, flavor,
                                                    name):  # fmt: skip
    if fmi == 2:
        folder = fmu_dir if flavor == "python" else native_dir
        messages = _fmi2_messages(folder / f"{name}.fmu")
    else:
        messages = _fmi3_messages(fmi3_dirs[flavor] / f"{name}.fmu")
    read = [parse_fmi_message(m, fmi) for m in messages]  # raises on a message that breaks it
    assert all(refs == [] for _, refs in read)  # our messages name no variable
    texts = [text for text, _ in read]
    assert len(texts) >= 6, texts  # every call's line, with logFmiCalls on
    named = [t for t in texts if NAME in t]
    assert len(named) >= 2 and any("nan" in t for t in named), texts[-3:]
    if name == "GliderObserver":
        assert any("does not match f_sample" in t for t in texts)


HARNESS = r"""
#include "onefmu_quiet.c"

static void host(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                 fmi2String category, fmi2String message, ...) {
    char text[20000];
    va_list ap;
    (void)env; (void)instance; (void)status; (void)category;
    va_start(ap, message);
    vsnprintf(text, sizeof(text), message, ap);
    va_end(ap);
    printf("%s\n", text);
}

static void call(const char *fmt, const char *a, const char *b) {
    wrap_t w;
    memset(&w, 0, sizeof(w));
    w.logger = host;
    quiet_logger(&w, "loop", fmi2Warning, "logStatusWarning", fmt, a, b);
}

int main(void) {
    static char longer[6000];
    memset(longer, '#', sizeof(longer) - 1);
    call("%s", "FMU#0: loading 'GliderPlant.so' (line #3, # Version 2)", NULL);
    call("%s: %s", "plant", "glider##1: m = nan ## #r12# # #r# #i7");
    call("%s: %s", "odd#name", "");
    call("%s", longer, NULL); /* 5999 '#' cut to the container's 4095: 8190 out */
    call("%s: %s", "p", longer); /* read as 2999 "##" and a lone '#': 3000, doubled */
    return 0;
}
"""


def test_the_forwarder_writes_by_the_rule_under_asan(tmp_path):
    """The forwarder's rewriting (onefmu_quiet.c) in a harness: -Wall -Wextra warning-free,
    run under AddressSanitizer and UBSan; each line read by the rule gives the text."""
    import glider_cosim.interop.onefmu as onefmu
    from glider_fmi.compile import fmi_headers

    c_file = tmp_path / "h.c"

    c_file.write_text(HARNESS)
    exe = tmp_path / "h"
    require_tool("gcc")
    p = subprocess.run(["gcc", "-std=gnu11", "-g", "-Wall", "-Wextra", "-Werror",
                        "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
                        f"-I{fmi_headers()}", f"-I{onefmu.QUIET_SOURCE.parent}", str(c_file),
                        "-o", str(exe), "-ldl", "-lpthread"],
                       capture_output=True, text=True)  # fmt: skip
    assert p.returncode == 0 and p.stderr == "", p.stderr
    p = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    lines = p.stdout.splitlines()
    read = [parse_fmi_message(line, 2) for line in lines]
    assert [r[1] for r in read] == [[]] * 5
    assert read[0][0] == "FMU#0: loading 'GliderPlant.so' (line #3, # Version 2)"
    # the embedded FMU's "##" is one '#'; its reference (of its own variable) stays text
    assert read[1][0] == "plant: glider#1: m = nan # #r12# # #r# #i7"
    assert read[2][0] == "odd#name: "
    assert len(lines[3]) == 8190 and read[3][0] == "#" * 4095
    assert read[4][0] == "p: " + "#" * 3000


VALGRIND_HOST = r"""
/* Loads a native FMU's binary, instantiates it under a name with a '#', every category
 * on, and has it refuse a NaN parameter; prints what reaches the logger, one per line. */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

typedef void (*log2_t)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    log2_t logger;
    void *(*alloc)(size_t, size_t);
    void (*release)(void *);
    void *step_finished;
    void *env;
} callbacks2_t;

static void host_log2(void *env, const char *name, int status, const char *cat,
                      const char *fmt, ...) {
    char text[4096];
    va_list ap;
    (void)env; (void)name; (void)status; (void)cat;
    va_start(ap, fmt);
    vsnprintf(text, sizeof(text), fmt, ap);
    va_end(ap);
    printf("%s\n", text);
}

static void host_log3(void *env, int status, const char *cat, const char *text) {
    (void)env; (void)status; (void)cat;
    printf("%s\n", text);
}

int main(int argc, char **argv) {
    /* argv: fmi (2|3), binary, token, resources, value reference of a Float64 parameter */
    const char *cats[] = {"logAll", "logFmiCalls"};
    unsigned vr;
    double nan_value = 0.0 / 0.0;
    void *lib, *c;
    if (argc != 6) return 2;
    vr = (unsigned)atoi(argv[5]);
    if (!(lib = dlopen(argv[2], RTLD_NOW | RTLD_LOCAL))) return 3;
    if (argv[1][0] == '2') {
        callbacks2_t cb = {host_log2, calloc, free, NULL, NULL};
        typedef void *(*inst2_t)(const char *, int, const char *, const char *,
                                 const callbacks2_t *, int, int);
        inst2_t inst = (inst2_t)dlsym(lib, "fmi2Instantiate");
        int (*debug)(void *, int, size_t, const char **) =
            (int (*)(void *, int, size_t, const char **))dlsym(lib, "fmi2SetDebugLogging");
        int (*setup)(void *, int, double, double, int, double) =
            (int (*)(void *, int, double, double, int, double))dlsym(lib, "fmi2SetupExperiment");
        int (*set)(void *, const unsigned *, size_t, const double *) =
            (int (*)(void *, const unsigned *, size_t, const double *))dlsym(lib, "fmi2SetReal");
        int (*mode)(void *) = (int (*)(void *))dlsym(lib, "fmi2EnterInitializationMode");
        int (*exit_mode)(void *) = (int (*)(void *))dlsym(lib, "fmi2ExitInitializationMode");
        void (*release)(void *) = (void (*)(void *))dlsym(lib, "fmi2FreeInstance");
        if (!(c = inst("glider#1", 1, argv[3], argv[4], &cb, 0, 1))) return 4;
        debug(c, 1, 2, cats);
        setup(c, 0, 0.0, 0.0, 0, 0.0);
        set(c, &vr, 1, &nan_value);
        mode(c);
        if (exit_mode(c) < 3) return 5;
        release(c);
    } else {
        void *(*inst)(const char *, const char *, const char *, int, int, int, int,
                      const unsigned *, size_t, void *, void *, void *) =
            (void *(*)(const char *, const char *, const char *, int, int, int, int,
                       const unsigned *, size_t, void *, void *, void *))
                dlsym(lib, "fmi3InstantiateCoSimulation");
        int (*debug)(void *, int, size_t, const char **) =
            (int (*)(void *, int, size_t, const char **))dlsym(lib, "fmi3SetDebugLogging");
        int (*set)(void *, const unsigned *, size_t, const double *, size_t) =
            (int (*)(void *, const unsigned *, size_t, const double *, size_t))
                dlsym(lib, "fmi3SetFloat64");
        int (*mode)(void *, int, double, double, int, double) =
            (int (*)(void *, int, double, double, int, double))
                dlsym(lib, "fmi3EnterInitializationMode");
        int (*exit_mode)(void *) = (int (*)(void *))dlsym(lib, "fmi3ExitInitializationMode");
        void (*release)(void *) = (void (*)(void *))dlsym(lib, "fmi3FreeInstance");
        if (!(c = inst("glider#1", argv[3], argv[4], 0, 1, 0, 0, NULL, 0, NULL, (void *)host_log3,
                       NULL))) return 4;
        debug(c, 1, 2, cats);
        set(c, &vr, 1, &nan_value, 1);
        mode(c, 0, 0.0, 0.0, 0, 0.0);
        if (exit_mode(c) < 3) return 5;
        release(c);
    }
    dlclose(lib);
    return 0;
}
"""


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_native_layers_messages_under_valgrind(native_dir, fmi3_dirs, tmp_path, fmi):
    """The layer's rewriting of each message (every '#' doubled; '%' too for FMI 2's
    printf-style logger) in a native FMU's binary, called from a C host under valgrind
    memcheck: no error, no leak, every line by the rule."""

    from fmpy import read_model_description

    from glider_cosim.master.instance import _extracted

    require_tool("valgrind")
    require_tool("gcc")
    c_file, exe = tmp_path / "host.c", tmp_path / "host"
    c_file.write_text(VALGRIND_HOST)
    p = subprocess.run(["gcc", "-std=gnu11", "-g", "-Wall", "-Wextra", "-Werror", str(c_file),
                        "-o", str(exe), "-ldl"], capture_output=True, text=True)  # fmt: skip
    assert p.returncode == 0 and p.stderr == "", p.stderr
    fmu = (native_dir if fmi == 2 else fmi3_dirs["native"]) / "GliderPlant.fmu"
    md = read_model_description(str(fmu))
    folder = Path(_extracted(fmu))
    platform = "linux64" if fmi == 2 else "x86_64-linux"
    binary = folder / "binaries" / platform / "GliderPlant.so"
    resources = (folder / "resources").as_uri() if fmi == 2 else f"{folder / 'resources'}/"
    vr = next(v.valueReference for v in md.modelVariables if v.name == "m")
    p = subprocess.run(["valgrind", "--error-exitcode=99", "--leak-check=full",
                        "--errors-for-leak-kinds=definite", str(exe), str(fmi), str(binary),
                        md.guid, resources, str(vr)], capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    assert "ERROR SUMMARY: 0 errors" in p.stderr
    texts = [parse_fmi_message(line, fmi)[0] for line in p.stdout.splitlines()]
    assert any(t.startswith("glider#1: ") and "m = nan is invalid" in t for t in texts), texts
