"""Fuzz of the front door: a seeded generator of mutated scenarios and corrupted SSPs,
each run by ``glider-cosim run`` in its own process with a timeout, two at a time.

For every case: exit code 0, 1 or 2 (never a signal, never a hang), no traceback, an
exit 2 is one line, nothing is written outside the output folder (the process runs in
an empty folder with the default ``--out``, so ``out/<name>`` is the only thing it may
create) and no temporary file is left (each process has its own empty ``$TMPDIR``).
"""

from __future__ import annotations

import concurrent.futures
import json
import math
import os
import random
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any

import pytest

from glider_cosim.interop.ssp_export import export_ssp
from glider_cosim.scenarios.scenario import parse_scenario

pytestmark = pytest.mark.integration
SEED = 13
N_SCENARIOS = 200
N_SSPS = 50
TIMEOUT = 60.0  # s per case (a refused case takes about 0.5 s, a 1 s run about 1 s)
CLI = "from glider_cosim.cli import console_main; console_main()"
LIMITS = ["--max-steps", "20000", "--max-extract-mb", "16", "--no-plots"]

NASTY: list[Any] = [
    0, -1, 1, 2, 3, 7, 0.0, -0.0, 1.7, -35.0, 1e-7, 5e-324, 1e-300, 1e300, 1e308,
    math.inf, -math.inf, math.nan, True, False, 2**31 - 1, 2**31, 4294967299, 2**63,
    -(2**31) - 1, 10**30, "1 deg", "-35 deg", "1e999 deg", "deg", "", "x" * 300,
    "../../x", "/tmp/abs", "..", "passivity", "pi", "pid", [], {}, [[[]]], {"a": {"b": 1}},
    "inf", "nan", "\u00e9\u4e2d", "a\nb",
]  # fmt: skip
WHEN = ["time >= 0.5", "time >= nan", "time >= 1e999", "time >= -inf", "time >= 5 deg",
        "plant.z >= 1 deg", "plant.z >= 0.01", "plant.theta_g <= -30 deg", "plant.nosuch >= 1",
        "foo.bar >= 1", "plant.z", ">= 1", "time >= " + "9" * 400, "plant.V <= true"]  # fmt: skip
NAMES = ["plant.theta_g", "plant.nosuch", "foo.bar", "plant", ".", "controller.delta_cmd",
         "observer.V_hat", "plant.V_0", "time", "plant.z.x", "x" * 300]  # fmt: skip
PLANT_KEYS = ["V_0", "theta_g_0", "alpha_0", "noise_seed", "noise_std", "K_M0", "delta_0",
              "delta_max", "h_max", "z_0", "V", "nosuch", "m", "K_q", "tau_servo"]  # fmt: skip
CONTROLLER_KEYS = ["law", "K_c", "K_P", "K_I", "t_enable", "delta_open", "delta_max", "nope"]
TOP_KEYS = ["name", "stop_time", "step", "coupling", "feedback", "with_observer", "record",
            "description", "unknown", "plant", "controller", "observer", "fmus", "inputs",
            "disturbance", "event"]  # fmt: skip


# ----------------------------------------------------------------------- TOML
def _key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(doc: dict[str, Any]) -> str:
    """Every key as ``key = value`` (tables inline): enough for any document here."""
    return "".join(f"{_key(k)} = {toml_value(v)}\n" for k, v in doc.items())


# ----------------------------------------------------------------- scenarios
def base_scenario() -> dict[str, Any]:
    return {
        "name": "fuzz",
        "stop_time": 1.0,
        "step": 0.02,
        "plant": {"theta_g_0": "-35 deg", "V_0": 0.2, "noise_std": 0.01, "noise_seed": 3},
        "controller": {"law": "passivity", "K_c": 10.0},
        "disturbance": [{"target": "plant.F_z", "kind": "pulse", "time": 0.2, "duration": 0.1,
                         "value": 0.3}],
        "event": [{"when": "plant.z >= 0.01", "set": {"controller.K_c": 6.0}}],
        "record": ["plant.theta_g", "controller.delta_cmd", "plant.z"],
    }  # fmt: skip


def mutate_scenario(rng: random.Random, fmu_pool: list[str]) -> str:
    """One mutated scenario as TOML text (1-3 mutations, sometimes a text-level one)."""
    doc = base_scenario()
    for _ in range(rng.randint(1, 3)):
        op = rng.randrange(9)
        if op == 0:  # a top-level value
            doc[rng.choice(TOP_KEYS)] = rng.choice(NASTY)
        elif op == 1:
            doc.setdefault("plant", {})
            if isinstance(doc["plant"], dict):
                doc["plant"][rng.choice(PLANT_KEYS)] = rng.choice(NASTY)
        elif op == 2:
            doc.setdefault("controller", {})
            if isinstance(doc["controller"], dict):
                doc["controller"][rng.choice(CONTROLLER_KEYS)] = rng.choice(NASTY)
        elif op == 3:
            ev = {"when": rng.choice(WHEN), "set": {rng.choice(NAMES): rng.choice(NASTY)}}
            if rng.random() < 0.5:
                ev["delay"] = rng.choice(NASTY)
            doc["event"] = [ev]
        elif op == 4:
            doc["record"] = rng.sample(NAMES, rng.randint(1, 3))
        elif op == 5:
            doc["fmus"] = {rng.choice(["plant", "observer", "controller", "x"]):
                           rng.choice(fmu_pool)}  # fmt: skip
        elif op == 6:
            d = {
                "target": rng.choice(NAMES + ["plant.F_x"]),
                "kind": rng.choice(["step", "pulse", "ramp"]),
                "time": rng.choice(NASTY),
                "value": rng.choice(NASTY),
            }
            doc["disturbance"] = [d]
        elif op == 7:
            doc.pop(rng.choice(list(doc)), None)
        else:
            doc["inputs"] = {rng.choice(["plant.F_x", "plant.nosuch", "x"]): rng.choice(NASTY)}
    text = to_toml(doc)
    if rng.random() < 0.15:  # text level: cut, garbage, duplicated line, deep nesting
        kind = rng.randrange(4)
        if kind == 0:
            text = text[: rng.randrange(len(text))]
        elif kind == 1:
            i = rng.randrange(len(text))
            text = text[:i] + "".join(chr(rng.randrange(1, 0x3000)) for _ in range(5)) + text[i:]
        elif kind == 2:
            lines = text.splitlines(keepends=True)
            text += rng.choice(lines)
        else:
            depth = rng.choice([300, 2000])
            text += "deep = " + "[" * depth + "]" * depth + "\n"
    return text


# ----------------------------------------------------------------------- SSPs
def rewrite(src: Path, dst: Path, replace: dict[str, bytes], drop=(), extra=()) -> None:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for name in zin.namelist():
            if name not in drop:
                zout.writestr(name, replace.get(name, zin.read(name)))
        for name, data in extra:
            zout.writestr(name, data)


def corrupt_ssp(rng: random.Random, good: Path, dst: Path) -> None:
    """One corrupted copy of the SSP ``good`` at ``dst``."""
    with zipfile.ZipFile(good) as z:
        ssd = z.read("SystemStructure.ssd").decode()
        members = z.namelist()
    op = rng.randrange(9)
    if op == 0:  # an attribute value
        attrs = list(re.finditer(r'(\w+)="([^"]*)"', ssd))
        m = rng.choice(attrs)
        value = rng.choice(["", "0", "-1", "5e-324", "1e-300", "nan", "inf", "1e999",
                            "4294967297", "../../../../etc/passwd", "/etc/passwd",
                            "file:///etc/passwd", "http://x/y.fmu", "x" * 300, "true"])  # fmt: skip
        ssd = ssd[: m.start(2)] + value + ssd[m.end(2) :]
        rewrite(good, dst, {"SystemStructure.ssd": ssd.encode()})
    elif op == 1:  # drop an element
        tags = list(re.finditer(r"<(ssd|ssv|ssc|osp):\w+[^>]*/>", ssd))
        m = rng.choice(tags)
        rewrite(good, dst, {"SystemStructure.ssd": (ssd[: m.start()] + ssd[m.end() :]).encode()})
    elif op == 2:  # cut the XML
        rewrite(good, dst, {"SystemStructure.ssd": ssd[: rng.randrange(len(ssd))].encode()})
    elif op == 3:  # garbled bytes in the archive
        data = bytearray(good.read_bytes())
        for _ in range(rng.randint(1, 20)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        dst.write_bytes(bytes(data))
    elif op == 4:  # cut the archive
        data = good.read_bytes()
        dst.write_bytes(data[: rng.randrange(len(data))])
    elif op == 5:  # drop a member
        rewrite(good, dst, {}, drop=[rng.choice(members)])
    elif op == 6:  # an evil member
        name = rng.choice(["../evil.txt", "/abs/evil.txt", "resources/../../evil.txt"])
        rewrite(good, dst, {}, extra=[(name, b"evil")])
    elif op == 7:  # one of the FMUs inside, incomplete or broken
        fmu = rng.choice([m for m in members if m.endswith(".fmu")])
        with zipfile.ZipFile(good) as z:
            inner = z.read(fmu)
        tmp_in, tmp_out = dst.with_suffix(".in.fmu"), dst.with_suffix(".out.fmu")
        tmp_in.write_bytes(inner)
        with zipfile.ZipFile(tmp_in) as z:
            names = z.namelist()
        victim = rng.choice([n for n in names if n.startswith(("binaries/linux64", "resources/s",
                             "modelDescription", f"resources/{Path(fmu).stem}.py"))])  # fmt: skip
        if rng.random() < 0.5:
            rewrite(tmp_in, tmp_out, {}, drop=[victim])
        else:
            rewrite(tmp_in, tmp_out, {victim: rng.randbytes(rng.choice([0, 4, 1000]))})
        rewrite(good, dst, {fmu: tmp_out.read_bytes()})
        tmp_in.unlink()
        tmp_out.unlink()
    else:  # a zip bomb (32 MiB of zeros, the limit is 16 MiB)
        shutil.copy(good, dst)
        with zipfile.ZipFile(dst, "a", zipfile.ZIP_DEFLATED) as z, z.open("bomb", "w") as f:
            for _ in range(32):
                f.write(bytes(1 << 20))


# ----------------------------------------------------------------------- runs
def run_case(case: Path, target: str, fmu_dir: Path) -> str | None:
    """Run ``glider-cosim run TARGET`` in ``case/cwd``: ``"ok"`` (exit 0), ``None`` (a
    clean exit 1 or 2) or a description of what went wrong."""
    cwd, tmp = case / "cwd", case / "tmp"
    cwd.mkdir()
    tmp.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "GLIDER_COSIM_TMP"}
    env["TMPDIR"] = str(tmp)
    try:
        args = ["run", target, "--fmu-dir", str(fmu_dir), *LIMITS]
        p = subprocess.run([sys.executable, "-c", CLI, *args], cwd=cwd,
                           env=env, capture_output=True, text=True, timeout=TIMEOUT)  # fmt: skip
    except subprocess.TimeoutExpired:
        return f"hang (> {TIMEOUT:g} s)"
    err = p.stderr
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("glider-cosim: note: ")]
    if p.returncode < 0:
        return f"killed by signal {-p.returncode}: {err[-300:]}"
    if p.returncode not in (0, 1, 2):
        return f"exit {p.returncode}: {err[-300:]}"
    if "Traceback" in err:
        return f"traceback: {err[-500:]}"
    if p.returncode == 2 and (len(lines) != 1 or "error: " not in lines[0]):
        return f"exit 2 without a one-line error: {err[-300:]}"
    written = sorted(x.name for x in cwd.iterdir())
    if written not in ([], ["out"]):
        return f"wrote outside out/: {written}"
    if written == ["out"]:
        inside = [x.name for x in (cwd / "out").iterdir()]
        if len(inside) > 1:
            return f"wrote more than one folder in out/: {inside}"
    left = sorted(x.name for x in tmp.iterdir())
    if left:
        return f"left temporary files: {left}"
    if sorted(x.name for x in case.iterdir()) != sorted(["cwd", "tmp", *INPUTS[case.name]]):
        return f"wrote next to the inputs: {sorted(x.name for x in case.iterdir())}"
    return None if p.returncode != 0 else "ok"


INPUTS: dict[str, list[str]] = {}


def test_fuzz_scenarios_and_ssps(fmu_dir, tmp_path):
    rng = random.Random(SEED)
    pool_dir = tmp_path / "pool"
    pool_dir.mkdir()
    (pool_dir / "text.fmu").write_text("not a zip")
    (pool_dir / "folder.fmu").mkdir()
    good_plant = fmu_dir / "GliderPlant.fmu"
    with zipfile.ZipFile(good_plant) as z:
        names = z.namelist()
    for i, victim in enumerate(
        [
            "binaries/linux64/GliderPlant.so",
            "resources/GliderPlant.py",
            "resources/slavemodule.txt",
            "modelDescription.xml",
        ]
    ):
        rewrite(good_plant, pool_dir / f"broken{i}.fmu", {}, drop=[victim])  # fmt: skip
    assert all(v in names for v in ["resources/slavemodule.txt", "modelDescription.xml"])
    fmu_pool = [str(good_plant), "/dev/zero", "/nonexistent.fmu", "../../pool/text.fmu",
                *(str(p) for p in sorted(pool_dir.iterdir())), ""]  # fmt: skip
    ssp_base = export_ssp(
        tmp_path / "base.ssp", parse_scenario({"name": "fuzz-ssp", "stop_time": 1.0}), fmu_dir
    )
    cases: list[tuple[Path, str]] = []
    root = tmp_path / "cases"
    for i in range(N_SCENARIOS):
        case = root / f"s{i:03d}"
        case.mkdir(parents=True)
        (case / "s.toml").write_text(mutate_scenario(rng, fmu_pool), encoding="utf-8")
        INPUTS[case.name] = ["s.toml"]
        cases.append((case, str(case / "s.toml")))
    for i in range(N_SSPS):
        case = root / f"p{i:03d}"
        case.mkdir(parents=True)
        corrupt_ssp(rng, ssp_base, case / "x.ssp")
        INPUTS[case.name] = ["x.ssp"]
        cases.append((case, str(case / "x.ssp")))
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        outcomes = list(pool.map(lambda c: run_case(*c, fmu_dir), cases))
    failures = [f"{c.name}: {o}" for (c, _), o in zip(cases, outcomes) if o not in (None, "ok")]
    assert not failures, f"{len(failures)} of {len(cases)} cases failed:\n" + "\n".join(
        failures[:10]
    )
    assert sorted(x.name for x in root.iterdir()) == sorted(c.name for c, _ in cases)
    assert len(os.listdir(tmp_path)) == 3  # pool, base.ssp, cases: nothing escaped
    # the generator reaches both sides of the door
    assert 5 <= outcomes.count("ok") <= len(cases) - 100, outcomes.count("ok")
