"""Writing built files: to a temporary name first, then renamed into place."""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def replacing(target: Path) -> Iterator[Path]:
    """A temporary path beside ``target``, unique to this call, moved onto ``target`` in
    one step when the block ends without an error (removed otherwise).

    Two processes building the same FMU at once each write their own file; a reader sees
    the old FMU or a complete new one, never a part.
    """
    part = target.with_name(f".{target.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.part")
    try:
        yield part
        part.replace(target)
    finally:
        part.unlink(missing_ok=True)
