"""``python -m glider_cosim.verify [--write] ...``: the ``verify`` subcommand of the CLI
(same options; ``--write`` is ``--write-references``)."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from ..cli.main import main as cli_main


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI's ``verify`` with ``argv``; the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    argv = ["--write-references" if a == "--write" else a for a in argv]
    return cli_main(["verify", *argv])


if __name__ == "__main__":
    sys.exit(main())
