"""The options of ``glider-cosim sweep`` (:func:`add_parser`); light (argparse only), so
that building the command line's parser imports neither Dask nor numpy. The sweep itself
is :mod:`.sweep`."""

from __future__ import annotations

from typing import Any

from ..fmus.options import add_fmu_options

_DESCRIPTION = """Run a parameter sweep or a Monte Carlo study on Dask.

Each --param INSTANCE.NAME=SPEC (repeatable) is a list (6,8,10), a range START:STOP:NUM
(NUM values, both ends included) or random draws around the nominal value,
uniform(-20%,+20%) or normal(20%) (absolute: uniform(LOW,HIGH), normal(SD)); lists and
ranges form a full grid. An interrupted sweep resumes where it stopped; a folder that
holds another sweep's results is refused."""


def add_parser(sub: Any) -> None:
    """Add the ``sweep`` sub-command to the CLI's sub-parsers."""
    s = sub.add_parser("sweep", help="parameter sweep / Monte Carlo on Dask",
                       description=_DESCRIPTION)  # fmt: skip
    s.add_argument("scenario", nargs="?", default=None, help="scenario (default: default)")
    s.add_argument("--param", action="append", default=[], metavar="INSTANCE.NAME=SPEC",
                   help="swept parameter (repeatable): 6,8,10 | 2:20:10 | uniform(-20%%,+20%%)"
                   " | normal(20%%)")  # fmt: skip
    s.add_argument("--samples", type=int, default=10, help="draws for random specs")
    s.add_argument("--seeds", type=int, default=None, help="noise seeds 0..N-1 per run")
    s.add_argument("--rng-seed", type=int, default=0, help="seed of the random draws")
    s.add_argument("--workers", type=int, default=2, help="local worker processes")
    s.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    s.add_argument("--out", default="out/sweep",
                   help="results folder: one sweep's (the same sweep resumes there)")  # fmt: skip
    s.add_argument("--format", choices=("csv", "parquet"), default="csv",
                   help="format of the sweep's table (parquet needs pyarrow)")  # fmt: skip
    s.add_argument("--trajectories", action="store_true", help="keep each run's results CSV")
    s.add_argument("--stop-time", type=float, default=None, help="stop time, s")
    add_fmu_options(s)
    s.add_argument("--restart", action="store_true",
                   help="replace the results in --out (another sweep's too)")  # fmt: skip
    s.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    s.add_argument("--dashboard", action="store_true", help="serve and print the Dask dashboard")
