"""Shared output and measurements of the benchmark scripts."""

from __future__ import annotations

import argparse
import json
from typing import Any


def parse_args(doc: str, *own: tuple[str, dict[str, Any]]) -> argparse.Namespace:
    """The command line of a script documented by ``doc``: its own options (flag and
    ``add_argument`` keywords), then ``--fmu-dir`` (default ``fmus``) and ``--json``."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    for flag, kw in own:
        ap.add_argument(flag, **kw)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--json", action="store_true")
    return ap.parse_args()


def emit(result: dict[str, Any], as_json: bool) -> None:
    """Print ``key: value`` lines (unless ``as_json``), then the JSON object as last line."""
    if not as_json:
        for k, v in result.items():
            print(f"{k}: {v}")
    print(json.dumps(result))


def rss_mib() -> float:
    """This process's resident memory now (VmRSS), in MiB; NaN where /proc has none."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")
