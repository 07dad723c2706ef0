"""``glider-cosim explore``: one self-contained page that runs the glider in the browser.

The page (``explore.html``) carries the three FMUs' WebAssembly modules and a small
co-simulation master in JavaScript (``explore.js``): every change of a slider or field
re-simulates the whole run in the page and redraws it. Nothing is fetched, no server.

The modules are the core modules of the FMUs' FMI-LS-WASM components (the FMI 3.0 native
FMUs' ``binaries/wasm32-wasip2/<id>.wasm``, :mod:`glider_cosim.fmus.wasm`), taken out of
the components as they are: the same C as the native libraries (model, back end, FMI layer)
with the canonical-ABI glue. The page's host speaks that ABI itself for the few calls a run
makes, so the page needs neither jco nor a bundler (nor npm in CI), and it runs exactly
the code the FMUs ship. The master repeats the exchange our Python master plans for the
scenario (Initialization Mode's inputs in the order of
:func:`glider_cosim.master.plan.initialization_order`, then the exchange of
:func:`glider_cosim.master.plan.plan_exchange`, per coupling): the same calls in the same
order, hence the same numbers (to the last bits of libm).
"""

from __future__ import annotations

import base64
import json
import zipfile
from pathlib import Path
from typing import Any

from ..fmus.wasm import WASM_PLATFORM
from ..master.plan import exchange_order, plan_exchange

#: the page's name in the output folder
PAGE = "explore.html"
#: what marks a page as ours (never write over a file glider-cosim did not write)
MARK = "<!-- glider-cosim explore -->"
#: the page must stay under this size
MAX_BYTES = 5 * 2**20


class ExploreError(ValueError):
    """The page cannot be written (an FMU without a component, a file not ours)."""


def core_module(component: bytes) -> bytes:
    """The first core module inside a component (ours: the model and the glue; the others
    wasm-tools adds are its small adapters), byte for byte."""
    if component[:8] != b"\0asm\x0d\0\x01\0":
        raise ExploreError("not a WebAssembly component")
    i = 8
    while i < len(component):
        sid, size, shift, i = component[i], 0, 0, i + 1
        while True:
            b = component[i]
            i += 1
            size |= (b & 0x7F) << shift
            shift += 7
            if not b & 0x80:
                break
        if sid == 1:  # a core module section
            return component[i : i + size]
        i += size
    raise ExploreError("the component holds no core module")


def _ops(instances: dict[str, Any], ex: Any) -> list[dict]:
    """The exchange of one communication point, in the master's order (as
    :func:`glider_cosim.master.plan.plan_calls` flattens it)."""

    def reads(n: str) -> list[dict]:
        return [{"read": True, "inst": n, "type": g.type, "vrs": list(g.vr),
                 "names": [f"{n}.{v}" for v in names]} for g, names in ex.read[n]]  # fmt: skip

    def writes(n: str) -> list[dict]:
        return [{"read": False, "inst": n, "type": g.type, "vrs": list(g.vr), "sources": srcs}
                for g, srcs in ex.write[n]]  # fmt: skip

    ops = [op for n in ex.plain for op in reads(n)]
    for n in ex.ft_order:
        ops += writes(n) + reads(n)
    return ops + [op for n in ex.plain for op in writes(n)]


def page_data(scenario: Any, fmu_dir: Path) -> dict:
    """What the page needs: the modules, the plans of both couplings, the variables and
    the scenario's settings (SI units: rad, s, Hz)."""
    from ..master import CoSimulation
    from ..scenarios.system import system_for
    from .metrics import reference_glide

    system = system_for(scenario, fmu_dir)
    what = [w for w, has in (("events", system.events), ("disturbances", system.disturbances),
                             ("input tables", system.tables),
                             ("external components", getattr(scenario, "external", None)))
            if has]  # fmt: skip
    if what:
        raise ExploreError(
            f"scenario {scenario.name} has {' and '.join(what)}: the explorer runs scenarios "
            "without events, disturbances, input tables or external components (expected "
            "one such as default)"
        )
    system.record = None  # every output: the page's plots and metrics need them
    sim = CoSimulation(system, step=scenario.step, coupling=scenario.coupling)
    sim.load()
    try:
        inst = sim.instances
        plans = {}
        for coupling in ("gauss-seidel", "jacobi"):
            exchange_order(inst, sim._sources, coupling)  # raises for an algebraic loop
            plans[coupling] = _ops(inst, plan_exchange(system, inst, sim._sources, coupling))
        ex = sim._exchange_plan
        modules, module_of = [], {}
        for name, i in inst.items():
            ident = i.md.coSimulation.modelIdentifier
            with zipfile.ZipFile(i.fmu) as z:
                try:
                    component = z.read(f"binaries/{WASM_PLATFORM}/{ident}.wasm")
                except KeyError:
                    raise ExploreError(
                        f"{i.fmu.name} has no WebAssembly component (binaries/{WASM_PLATFORM}/): "
                        "build the native FMI 3 FMUs with wasm-tools installed"
                    ) from None
            module_of[name] = len(modules)
            modules.append(base64.b64encode(core_module(component)).decode())
        variables = {n: {v.name: {"vr": v.valueReference, "type": v.type} for v in i.vars.values()}
                     for n, i in inst.items()}  # fmt: skip
        init_order = []  # the inputs set in Initialization Mode (master.initial), in order
        for dst, src in sim._init_order:
            (di, dv), (si, sv) = sim._resolve(dst), sim._resolve(src)
            init_order.append({"dst": di.name, "dvr": dv.valueReference, "src": si.name,
                               "svr": sv.valueReference, "type": dv.type})  # fmt: skip
        driven = [{"inst": i.name, "vrs": list(g.vr),
                   "values": [float(system.driven.get(r, 0.0)) for r in refs]}
                  for i, g, refs in ex.driven]  # fmt: skip
        params = system.parameters
        ctrl, plant = params.get("controller", {}), params.get("plant", {})
        start = {n: {v.name: v.start for v in i.md.modelVariables if v.start is not None}
                 for n, i in inst.items()}  # fmt: skip

        def value(name: str, key: str) -> float:
            return float(params.get(name, {}).get(key, start[name][key]))

        from glider_plant.params import GliderParams

        # the glide the loop should reach, per law: the equilibrium, the held tail's glide
        p = GliderParams.from_mapping(plant)
        theta_ge = {"closed": reference_glide(p, {**ctrl, "law": 1})[0],
                    "open": reference_glide(p, {**ctrl, "law": 0})[0]}  # fmt: skip
        law = {0: "open loop", 1: "passivity", 2: "P", 3: "PI"}[int(value("controller", "law"))]
        defaults = {
            "law": law, "K_c": value("controller", "K_c"), "K_P": value("controller", "K_P"),
            "K_I": value("controller", "K_I"), "noise_std": value("plant", "noise_std"),
            "tau_servo": value("plant", "tau_servo"), "theta_g_0": value("plant", "theta_g_0"),
            "f_cutoff": value("observer", "f_cutoff"),
            "coupling": scenario.coupling, "stop_time": float(scenario.stop_time),
        }  # fmt: skip
        return {
            "scenario": scenario.name,
            "instances": list(inst),
            "guids": {n: i.md.guid for n, i in inst.items()},
            "modules": modules,
            "module_of": module_of,
            "plans": plans,
            "record": [c for c in sim.columns if c != "time"],
            "needed": list(ex.values),
            "variables": variables,
            "parameters": params,
            "driven": driven,
            "init_order": init_order,
            "step": float(scenario.step),
            "t0": 0.0,
            "theta_ge": theta_ge,
            "defaults": defaults,
        }
    finally:
        sim.close()


def _json(data: Any) -> str:
    """JSON for a script element (no ``</`` that would end it); non-finite floats refused."""
    return json.dumps(data, allow_nan=False, separators=(",", ":")).replace("</", "<\\/")


def page_html(data: dict) -> str:
    """The page: the data, the host and master script, the form and the canvases."""
    script = (Path(__file__).with_name("explore.js")).read_text(encoding="utf-8")
    canvases = "".join(
        f'<canvas id="c-{p}" width="620" height="230"></canvas>'
        for p in ("glide", "pitch", "tail", "speed")
    )
    title = f"glider-cosim explorer: {data['scenario']}"
    return f"""<!DOCTYPE html>
{MARK}
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ font-family: sans-serif; margin: 16px; color: #222; }}
#form {{ display: grid; grid-template-columns: repeat(2, minmax(280px, 1fr)); gap: 4px 24px;
  max-width: 1260px; }}
#form label {{ display: flex; align-items: center; gap: 8px; font-size: 14px; }}
#form input[type=range] {{ flex: 1; }}
#plots {{ display: grid; grid-template-columns: repeat(2, 620px); gap: 8px; margin-top: 12px; }}
canvas {{ border: 1px solid #ddd; }}
#metrics {{ margin-top: 10px; font-weight: bold; }} #timing {{ color: #555; font-size: 13px; }}
</style></head><body>
<h1 style="font-size:20px">{title}</h1>
<p style="max-width:1200px;font-size:14px"><b>Open this file in a browser; no server needed</b>
(a copy of it works anywhere, offline). The glider's plant, observer and controller FMUs run
in this page as WebAssembly (the core modules of their FMI-LS-WASM components), under a
co-simulation master in JavaScript. Every change re-simulates the whole run. The
passivity law divides by K_c: a larger K_c is a gentler controller (K_c = 5 swings in a
limit cycle, 10 settles). A law's unused gains are greyed out.
API: <code>await window.glider.ready; window.glider.simulate({{law: "PI", K_P: 0.5}})</code>
with any of <code>law</code> ("passivity", "P", "PI", "open loop"), <code>K_c</code>,
<code>K_P</code>, <code>K_I</code>, <code>noise_std</code> (rad), <code>tau_servo</code> (s),
<code>f_cutoff</code> (Hz), <code>theta_g_0</code> (rad), <code>coupling</code>,
<code>stop_time</code> (s) (the others: <code>window.glider.defaults</code>) returns
<code>{{time: [...], "plant.theta_g": [...], ..., metrics, status, message, messages,
elapsed_ms}}</code>.</p>
<div id="form"></div><div id="metrics"></div><div id="timing"></div>
<div id="plots">{canvases}</div>
<script>const GLIDER_DATA = {_json(data)};</script>
<script>{script}</script>
</body></html>
"""


def write_page(out: Path, scenario: Any, fmu_dir: Path) -> Path:
    """Write ``out/explore.html`` (the folder created); refuses to write over a file that
    is not such a page.

    Raises
    ------
    ExploreError
        The file there is not ours, an FMU has no component, or the page is too large.
    """
    page = Path(out) / PAGE
    if page.exists() and (not page.is_file() or MARK not in page.read_text(errors="replace")):
        raise ExploreError(f"{page} exists and is not an explorer page of glider-cosim: "
                           "expected a new file or one explore wrote")  # fmt: skip
    html = page_html(page_data(scenario, fmu_dir))
    size = len(html.encode())
    if size > MAX_BYTES:
        raise ExploreError(f"the page would be {size / 2**20:.1f} MB: expected at most 5 MB")
    page.parent.mkdir(parents=True, exist_ok=True)
    part = page.with_name(page.name + ".part")
    part.write_text(html, encoding="utf-8")
    part.replace(page)
    return page


__all__ = ["ExploreError", "core_module", "page_data", "page_html", "write_page"]


def explore(
    scenario: str | Path | None = None,
    out: str | Path | None = None,
    *,
    fmu_dir: str | Path | None = None,
    overwrite_fmus: bool = False,
) -> Path:
    """Write the explorer page of a scenario: what ``glider-cosim explore`` does.

    Parameters
    ----------
    scenario : path or shipped name, optional
        A TOML file or a shipped scenario's name (default: the default scenario).
    out : path, optional
        The page's folder (default: ``out/<scenario>-explore``), checked first.
    fmu_dir : path, optional
        Native FMI 3 FMUs with their WebAssembly components (default: the per-user
        cache's, built if missing or stale).
    overwrite_fmus : bool
        Replace what ``fmu_dir`` holds under our FMUs' names.

    Returns
    -------
    Path
        ``explore.html``.
    """
    from ..fmus.folders import prepare_fmus
    from ..inputs.outputs import check_out_dir
    from ..scenarios.scenario import load_scenario

    loaded = load_scenario(scenario)
    out = Path(out) if out is not None else Path("out") / f"{loaded.name}-explore"
    check_out_dir(out, "--out")
    folder = None if fmu_dir is None else Path(fmu_dir)
    fmus = prepare_fmus(folder, "native", 3, host_only=folder is None, overwrite=overwrite_fmus)
    return write_page(out, loaded, fmus)
