"""The command line's parser: every subcommand, its options and their defaults
(tests/test_cli_light.py)."""

from __future__ import annotations

import argparse
import re

from ..components import COMPONENTS
from ..fmus.options import FLAVORS, FMI_VERSIONS, add_fmu_options, add_overwrite_option
from ..inputs.text import did_you_mean, one_line, prefix
from ..master.spec import DEFAULT_MAX_STEPS
from ..scenarios.scenario import shipped_scenarios
from .argtypes import _count, _non_negative, _positive


class UsageError(ValueError):
    """A command-line argument cannot be used (the message names the option)."""


class _Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Plain-text help: defaults shown, reST markup of the docstrings removed."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return super()._fill_text(_plain(text), width, indent)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = _plain(action.help or "")
        if action.default in (None, False, [], argparse.SUPPRESS) or "%(default)" in text:
            return text
        if "default" in text:
            return text
        return text + " (default: %(default)s)"


def uses_fmu_options(args: argparse.Namespace) -> bool:
    """True if ``--fmu-dir``/``--flavor`` name FMUs to prepare (not verify's; analyze's with
    ``--from-fmu`` only: without it they are refused, the model's Jacobian uses no FMU)."""
    if args.command == "analyze" and not args.from_fmu:
        given = [o for o in ("fmu_dir", "flavor", "fmi") if getattr(args, o) is not None]
        if given:
            raise UsageError(f"--{given[0].replace('_', '-')} needs --from-fmu (the model's "
                             "own Jacobian uses no FMU)")  # fmt: skip
        return False
    return hasattr(args, "fmu_dir") and args.command != "verify" and hasattr(args, "flavor")


def _plain(text: str) -> str:
    text = re.sub(r":\w+:`~?([^`]+)`", r"\1", text)
    return text.replace("``", "'")


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", _Formatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # one line, exit code 2
        self.exit(2, f"{prefix('error', self.prog.partition(' ')[2])}{one_line(message)}\n")

    def _check_value(self, action: argparse.Action, value: object) -> None:
        """argparse's check of ``choices``, with a "did you mean" for a misspelt choice
        (a subcommand, ``--coupling jacobe``)."""
        choices = action.choices
        if choices is not None and value not in choices:
            shown = ", ".join(repr(c) for c in choices)
            raise argparse.ArgumentError(
                action, f"invalid choice: {value!r} (choose from {shown})"
                + did_you_mean(value, choices)
            )  # fmt: skip


def _version() -> str:
    """glider-cosim's version (the installed distribution's: it is read from the same
    place, :data:`glider_cosim.__version__`)."""
    from ..fmus.files import package_version

    return package_version()


class _Commands(argparse._SubParsersAction):
    """The subcommands; with ``only`` given, the other commands are named (with their help:
    the usage, the list and "did you mean" are whole) but their options are not made, as
    parsing one command needs only its own (``main``: 10 ms of every command, issue 48)."""

    def __init__(self, *args, only: str | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.only = only

    def add_parser(self, name: str, **kwargs) -> argparse.ArgumentParser:
        parser = super().add_parser(name, **kwargs)
        if self.only is not None and name != self.only:
            parser.add_argument = parser.add_argument_group = _UNBUILT  # type: ignore[method-assign]
            parser.add_mutually_exclusive_group = parser.set_defaults = _UNBUILT  # type: ignore[method-assign]
        return parser


class _Unbuilt:
    """An unbuilt command's ``add_argument`` and groups: take any call, make nothing."""

    def __call__(self, *args: object, **kwargs: object) -> _Unbuilt:
        return self

    def __getattr__(self, name: str) -> _Unbuilt:
        return self


_UNBUILT = _Unbuilt()


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``glider-cosim`` parser: every subcommand, its options and their defaults.

    ``command``: the options of that command alone (what :func:`~.main.main` parses with;
    any other command would be refused as having no such option)."""
    p = _Parser(prog="glider-cosim", description=__doc__)
    p.add_argument(
        "--version",
        action="version",
        version=f"glider-cosim {_version()}",
        help="print glider-cosim's version and exit",
    )
    # not required: a bare ``glider-cosim`` lists the commands (main.py, :func:`overview`)
    sub = p.add_subparsers(dest="command", parser_class=_Parser, action=_Commands,
                           only=command)  # fmt: skip

    b = sub.add_parser("build", help="build the three FMUs", description="Build the three FMUs.")
    b.add_argument(
        "--out",
        default=None,
        help="output folder (default: fmus, fmus/native for native, fmus/fmi3 and "
        "fmus/fmi3/native with --fmi 3)",
    )
    b.add_argument(
        "--flavor", choices=FLAVORS, default="python", help="Python reference or native C99"
    )
    b.add_argument(
        "--fmi", type=int, choices=FMI_VERSIONS, default=2, help="FMI version: 2.0 or 3.0"
    )
    b.add_argument(
        "--compiler",
        default=None,
        metavar="CC[,CC...]",
        help="C compilers: zig (default, from PyPI: every platform) or system ones, e.g. "
        "gcc, clang, x86_64-w64-mingw32-gcc, each building the platform it targets, zig "
        "the others (default: $GLIDER_COSIM_COMPILER, else zig)",
    )
    add_overwrite_option(b, "--out")

    r = sub.add_parser(
        "run",
        help="run a scenario or an SSP (default: the paper's Sec. 3.3 case)",
        description="Run a TOML scenario, a shipped scenario or an SSP (.ssp archive, .ssd\n"
        "file) with our master; write results.csv, metrics.json and PNG plots.",
    )
    r.add_argument(
        "scenario",
        nargs="?",
        default=None,
        help=f"TOML file, shipped name ({', '.join(shipped_scenarios())}) or .ssp/.ssd "
        "file; default: default",
    )
    r.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="results folder, written straight into (default: out/<scenario>); results "
        "an earlier run made there with other settings are replaced, with a note naming them",
    )
    add_fmu_options(r, fmi=True, wasm=True)
    r.add_argument(
        "--coupling",
        type=str.lower,
        choices=("gauss-seidel", "jacobi"),
        default=None,
        help="coupling scheme (default: the scenario's, gauss-seidel for an SSP)",
    )
    r.add_argument(
        "--step",
        type=_positive,
        default=None,
        help="communication step, s (default: the scenario's)",
    )
    r.add_argument(
        "--stop-time", type=_positive, default=None, help="stop time, s (default: the scenario's)"
    )
    r.add_argument("--no-plots", action="store_true", help="skip the PNG plots and plots.html")
    r.add_argument(
        "--format",
        choices=("csv", "parquet"),
        default="csv",
        help="results file: results.csv (text) or results.parquet (binary float64, read by "
        "pandas and polars; needs pyarrow)",
    )
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="INSTANCE.NAME=VALUE",
        help="override a parameter (repeatable): controller.K_c=6, plant.theta_g_0='-30 deg'",
    )
    r.add_argument(
        "--max-steps", type=_count, default=DEFAULT_MAX_STEPS, help="most communication steps"
    )
    r.add_argument(
        "--max-extract-mb",
        type=_count,
        default=256,
        help="most MiB one FMU or SSP archive may unpack to",
    )
    r.add_argument(
        "--real-time",
        action="store_true",
        help="pace the communication points to the wall clock (docs/how-to/real-time.md)",
    )
    r.add_argument(
        "--rtf",
        type=_positive,
        default=None,
        help="with --real-time: real-time factor, 1 real time (default), 0.5 half, 2 twice",
    )
    r.add_argument(
        "--max-lateness-ms",
        type=_positive,
        default=None,
        help="with --real-time: stop the run when a point starts later than this, ms",
    )
    r.add_argument(
        "--spin-ms",
        type=_non_negative,
        default=None,
        help="with --real-time: spin this long before each point instead of sleeping, ms "
        "(default 1.5; 20 or more at 50 Hz never sleeps and keeps a core busy)",
    )
    r.add_argument(
        "--external",
        action="append",
        default=[],
        metavar="COMPONENT=udp://HOST:PORT",
        help="that component is an endpoint outside the process (repeatable)",
    )
    r.add_argument(
        "--external-timeout",
        type=_positive,
        default=None,
        help="seconds an external endpoint may stay silent before the run stops (default 5)",
    )

    sv = sub.add_parser(
        "serve",
        help="serve a component's FMU as a UDP endpoint (docs/how-to/real-time.md)",
    )
    sv.add_argument("component", choices=tuple(c.name for c in COMPONENTS))
    sv.add_argument("--listen", default="udp://127.0.0.1:9870", help="udp://HOST:PORT")
    sv.add_argument("--fmu", default=None, help="the FMU to serve (default: ours)")
    sv.add_argument(
        "--flavor", choices=("native", "python"), default="native", help="our FMU's flavor"
    )
    sv.add_argument("--once", action="store_true", help="exit after the first session")

    ob = sub.add_parser(
        "build-onboard",
        help="build the native controller as a standalone endpoint program (no Python, no FMI)",
    )
    ob.add_argument("component", choices=("controller",))
    ob.add_argument("--target", default=None, help="zig target, e.g. aarch64-linux-musl")
    ob.add_argument("--out", required=True, help="output folder")

    e = sub.add_parser(
        "export-ssp", help="write the system as an SSP archive (1.0; 2.0 for FMI 3.0 FMUs)"
    )
    e.add_argument("out", metavar="OUT", help="output .ssp file, in a folder that exists")
    e.add_argument("scenario", nargs="?", default=None, help="scenario; default: default")
    e.add_argument(
        "--ssp-version",
        choices=("1.0", "2.0"),
        default=None,
        help="SSP version to write (default: 1.0 for FMI 2.0 FMUs, 2.0 for FMI 3.0 ones; "
        "1.0 for FMI 3.0 FMUs types them as SSP 1.0's Real/Integer, for importers that "
        "read only 1.0, such as Ecos 0.7)",
    )
    add_fmu_options(e, fmi=True)

    he = sub.add_parser(
        "host-env", help="environment a C/C++ host on another machine needs for our FMUs"
    )
    he.add_argument(
        "--config",
        action="store_true",
        help="print the FMU runtime's Python configuration instead (for GLIDER_FMI_PYTHON_CONFIG)",
    )

    xf = sub.add_parser(
        "export-fmu",
        help="the closed loop as one co-simulation FMU",
        description="Write a scenario's closed loop as one FMI 2.0 co-simulation FMU (a container\n"
        "of the three FMUs). Inside, the FMUs run with Jacobi coupling: all step, then the\n"
        "outputs are copied to the inputs, one sample more from measurement to actuation\n"
        "than the Gauss-Seidel coupling `glider-cosim run` uses by default. Its results\n"
        "equal `glider-cosim run --coupling jacobi` bit for bit and differ from the\n"
        "default run by up to 0.47 deg in glide angle on the default scenario.",
    )
    xf.add_argument("out", metavar="OUT", help="output .fmu file, in a folder that exists")
    xf.add_argument("scenario", nargs="?", default=None, help="scenario; default: default")
    add_fmu_options(xf)

    rep = sub.add_parser("report", help="run every figure's scenario and write report.md")
    rep.add_argument("--out", default="out/report", help="report folder")
    add_fmu_options(rep)
    rep.add_argument("--no-progress", action="store_true", help="the same as --quiet")
    rep.add_argument("--no-plots", action="store_true",
                     help="skip report.html (the PNGs stay: report.md shows them)")  # fmt: skip
    rep.add_argument("--roa-grid", default="7x5", metavar="NxM|none",
                     help="region-of-attraction grid: N glide angles x M speeds (default "
                     "7x5; none: skip the map)")  # fmt: skip
    rep.add_argument("--workers", type=int, default=2, help="local Dask workers for the map")
    rep.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")

    xp = sub.add_parser(
        "explore",
        help="write a page that runs the glider in the browser, live",
        description="Write one self-contained explore.html: the three FMUs' WebAssembly\n"
        "modules under a master in the page; every slider re-simulates the run.",
    )
    xp.add_argument("scenario", nargs="?", default=None,
                    help="TOML file or shipped name; default: default")  # fmt: skip
    xp.add_argument("--out", default=None, metavar="DIR",
                    help="folder of explore.html (default: out/<scenario>-explore)")  # fmt: skip
    xp.add_argument("--fmu-dir", default=None,
                    help="native FMI 3 FMUs with their components (default: the per-user "
                    "cache's, built if missing)")  # fmt: skip
    add_overwrite_option(xp)

    a = sub.add_parser("analyze", help="equilibrium, eigenvalues, stable K_c range")
    a.add_argument("--json", action="store_true", help="one JSON object on stdout")
    a.add_argument("--from-fmu", action="store_true",
                   help="the continuous-time Jacobian from the plant FMU's directional "
                   "derivatives (of the --flavor and --fmi asked) instead of the model's "
                   "central differences")  # fmt: skip
    add_fmu_options(a, fmi=True)

    from ..sweeps.options import add_parser as add_sweep_parser

    add_sweep_parser(sub)
    v = sub.add_parser(
        "verify",
        help="run the experiments an FMU carries (FMI-LS-REF), or the verification kit",
        description="Run the FMI-LS-REF experiments an FMU carries (its files' checksums\n"
        "first). Else (or with --kit): a controller or estimator gets the loop's checks\n"
        "(interface, units, outputs in Initialization Mode, none one step late, the\n"
        "default start settling), then the reference cases (counted for a port of our\n"
        "laws only); a plant, or --case: the cases against the references. Exit 0 if\n"
        "all counted pass, 1 if one failed or a file changed after the FMU was built,\n"
        "2 on bad input, a missing interface or nothing that can run.",
    )
    if command in (None, "verify"):
        from ..verify.command import add_arguments, tolerance_arg

        add_arguments(v, tolerance_arg)
    ae = sub.add_parser("add-experiments", help="write an FMI-LS-REF experiment into a copy "
                        "of your FMU, from a run of our loop around it")  # fmt: skip
    if command in (None, "add-experiments"):
        from ..verify.command import add_experiments_arguments

        add_experiments_arguments(ae)
    cm = sub.add_parser(
        "compare",
        help="your controller or estimator against ours, on the paper's benchmark set",
        description="The paper's benchmark set with the scenario's [fmus] component and with\n"
        "ours, on our master and plant: compare.md/.html/.csv, an overlay figure per case.\n"
        "Exit 0 when the runs complete, whatever the comparison says; 2 on bad input.",
    )
    cm.add_argument("scenario", metavar="SCENARIO", help="TOML file whose [fmus] swaps the "
                    "controller or the observer")  # fmt: skip
    cm.add_argument("--out", default=None, metavar="DIR", help="output folder (default: "
                    "out/<scenario>-compare)")  # fmt: skip
    add_fmu_options(cm)
    sub.add_parser(
        "scenarios",
        help="list the shipped scenarios, one line each",
        description="List the shipped scenarios: each name and what it is, in one line.",
    )
    ca = sub.add_parser(
        "cache",
        help="list the cached FMU sets with their sizes",
        description="List the per-user cache of built FMUs ($GLIDER_COSIM_CACHE, else\n"
        "$XDG_CACHE_HOME/glider-cosim or the platform's cache folder) with sizes.",
    )
    ca.add_argument(
        "--prune",
        action="store_true",
        help="remove the folders of other glider-cosim versions (this version's sets of "
        "other sources are kept)",
    )
    for command in sub.choices.values():  # every command: builds, runs and sweeps wait
        command.add_argument("-q", "--quiet", action="store_true", help=QUIET_HELP)
    return p


#: ``--quiet``'s help, on every command
QUIET_HELP = (
    "no progress on stderr (default: off, so every wait over 2 s shows what is being done "
    "and how far: a bar on a terminal, plain lines in a pipe, a file or CI); results, "
    "notes and errors still print"
)
