"""Load an HTML page in headless Chromium (Debian's ``chromium``) and report what rendered.

A copy of the page gets two probe scripts: one first in ``<head>`` records console errors
and uncaught exceptions, one after load counts, per ``.glider-figure`` block, the drawn
canvases (bokeh draws inside shadow roots, which ``--dump-dom`` does not show) and writes
the counts into the dumped DOM. Chromium's own console log (stderr) is checked as well.
:func:`layout` reads back where bokeh placed each plot of a page at a window width.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

_HEAD = """<script>window.__errors=[];(function(){const e=console.error.bind(console);
console.error=function(...a){window.__errors.push(a.map(String).join(' '));e(...a);};
window.addEventListener('error',ev=>window.__errors.push('uncaught: '+ev.message));})();
</script>"""
_TAIL = """<script>window.addEventListener('load',()=>setTimeout(()=>{
function canv(n){let c=0;for(const el of n.querySelectorAll('*')){
if(el.tagName==='CANVAS'&&el.width>0&&el.height>0)c++;if(el.shadowRoot)c+=canv(el.shadowRoot);}
return c;}
const figs=[...document.querySelectorAll('.glider-figure')].map(canv);
const out=document.createElement('pre');out.id='probe';
out.textContent=JSON.stringify({figures:figs,errors:window.__errors,
fetched:performance.getEntriesByType('resource').map(e=>e.name)});
document.body.appendChild(out);},1500));</script>"""


def chromium() -> str | None:
    """The Chromium binary, or None."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


def _probed(page: Path, text: str, options: list[str], timeout: float) -> tuple[dict, str]:
    """Chromium's ``--dump-dom`` of ``text`` (``page`` with a probe script that writes
    ``<pre id="probe">JSON</pre>``): (that JSON, chromium's stderr)."""
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / page.name
        copy.write_text(text, encoding="utf-8")
        proc = subprocess.run(
            [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
             f"--user-data-dir={tmp}/profile", *options, "--virtual-time-budget=20000",
             "--dump-dom", copy.as_uri()],
            capture_output=True, text=True, timeout=timeout, check=False,
        )  # fmt: skip
    m = re.search(r'<pre id="probe">(.*?)</pre>', proc.stdout, re.S)
    if not m:
        raise AssertionError(f"the page's probe did not run; chromium said: {proc.stderr[-2000:]}")
    return json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&")), proc.stderr


def load(page: Path, timeout: float = 120.0) -> dict:
    """``{"figures": [canvases per figure], "errors": [...], "console": [...],
    "fetched": [every resource the page loaded]}``."""
    text = page.read_text(encoding="utf-8")
    probed = text.replace("<head>", "<head>" + _HEAD, 1).replace("</body>", _TAIL + "</body>", 1)
    found, stderr = _probed(page, probed, ["--enable-logging=stderr", "--v=0"], timeout)
    found["console"] = [ln for ln in stderr.splitlines()
                        if "CONSOLE" in ln and ("rror" in ln or "Uncaught" in ln)]  # fmt: skip
    return found


def screenshot(page: Path, png: Path, size: str = "1400,1000") -> None:
    """A screenshot of the page as it renders."""
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
             f"--user-data-dir={tmp}/profile", f"--window-size={size}",
             "--virtual-time-budget=20000", f"--screenshot={png}", page.as_uri()],
            capture_output=True, text=True, timeout=120, check=True,
        )  # fmt: skip


#: per plot (not the plot that holds a grid's legend, named ``glider-legend``): its
#: figure (the ``.glider-figure`` block it is in), its frame's size, a
#: legend beside it, its tick labels as bokeh lays them out ([lo, hi] px along the
#: axis, every label of the ticker); per figure block: what is drawn into its
#: ``glider-figure-N`` element, in order (tag, class, text of a heading, top and bottom px)
_LAYOUT = """<script>window.addEventListener('load',()=>setTimeout(()=>{let out;try{
const blocks=[...document.querySelectorAll('.glider-figure')];
const rects=blocks.map(e=>e.getBoundingClientRect());
function plots(v,acc){if(v.frame&&v.model.name!=='glider-legend')acc.push(v);
for(const c of (v.child_views||[]))plots(c,acc);return acc;}
function labels(pv,dim){const ax=[...pv.axis_views].find(a=>a.dimension===dim);
const ticks=ax.tick_coords.major[dim],lab=ax.compute_labels(ticks);
lab.visuals=ax.visuals.major_label_text.values();
const scale=dim===0?pv.frame.x_scale:pv.frame.y_scale;
return ticks.map((t,k)=>{const c=scale.compute(t),s=lab.items[k].size(),
h=(dim===0?s.width:s.height)/2;return [c-h,c+h];}).sort((a,b)=>a[0]-b[0]);}
const found=[];
for(const root of Bokeh.index.roots)for(const pv of plots(root,[])){
const r=pv.el.getBoundingClientRect(),cy=(r.top+r.bottom)/2;
found.push({figure:rects.findIndex(f=>f.top<=cy&&cy<=f.bottom),left:r.left,top:r.top,
bottom:r.bottom,
width:pv.frame.bbox.width,height:pv.frame.bbox.height,
legend_beside:[...pv.model.left,...pv.model.right].some(m=>m.type==='Legend'),
title:pv.model.title?pv.model.title.text:'',x:labels(pv,0),y:labels(pv,1)});}
const inner=(b)=>b.querySelector('[id^=glider-figure-]')||b;
const children=blocks.map(b=>[...inner(b).children].map(c=>{const q=c.getBoundingClientRect();
return {tag:c.tagName.toLowerCase(),cls:c.className,text:c.tagName==='H3'?c.textContent:'',
top:q.top,bottom:q.bottom};}));
out={plots:found,blocks:children};}catch(e){out={error:String(e)+' '+e.stack};}
const pre=document.createElement('pre');pre.id='probe';pre.textContent=JSON.stringify(out);
document.body.appendChild(pre);},1500));</script>"""


def layout(page: Path, width: int, timeout: float = 120.0) -> dict:
    """``{"plots": [...], "blocks": [...]}`` of ``page`` in a window ``width`` px wide
    (:data:`_LAYOUT`)."""
    text = page.read_text(encoding="utf-8").replace("</body>", _LAYOUT + "</body>", 1)
    found, _ = _probed(page, text, [f"--window-size={width},2000", "--hide-scrollbars"], timeout)
    if "error" in found:
        raise AssertionError(f"the layout probe failed: {found['error']}")
    return found
