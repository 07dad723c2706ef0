"""Load an HTML page in headless Chromium (Debian's ``chromium``) and report what rendered.

A copy of the page gets two probe scripts: one first in ``<head>`` records console errors
and uncaught exceptions, one after load counts, per ``.glider-figure`` block, the drawn
canvases (bokeh draws inside shadow roots, which ``--dump-dom`` does not show) and writes
the counts into the dumped DOM. Chromium's own console log (stderr) is checked as well.
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


def load(page: Path, timeout: float = 120.0) -> dict:
    """``{"figures": [canvases per figure], "errors": [...], "console": [...],
    "fetched": [every resource the page loaded]}``."""
    text = page.read_text(encoding="utf-8")
    probed = text.replace("<head>", "<head>" + _HEAD, 1).replace("</body>", _TAIL + "</body>", 1)
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / page.name
        copy.write_text(probed, encoding="utf-8")
        proc = subprocess.run(
            [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
             f"--user-data-dir={tmp}/profile", "--enable-logging=stderr", "--v=0",
             "--virtual-time-budget=20000", "--dump-dom", copy.as_uri()],
            capture_output=True, text=True, timeout=timeout, check=False,
        )  # fmt: skip
    m = re.search(r'<pre id="probe">(.*?)</pre>', proc.stdout, re.S)
    if not m:
        raise AssertionError(f"the page's probe did not run; chromium said: {proc.stderr[-2000:]}")
    found = json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    found["console"] = [ln for ln in proc.stderr.splitlines()
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
