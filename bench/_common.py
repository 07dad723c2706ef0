"""Shared output of the benchmark scripts."""

from __future__ import annotations

import json
from typing import Any


def emit(result: dict[str, Any], as_json: bool) -> None:
    """Print ``key: value`` lines (unless ``as_json``), then the JSON object as last line."""
    if not as_json:
        for k, v in result.items():
            print(f"{k}: {v}")
    print(json.dumps(result))
