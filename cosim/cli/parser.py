"""The command line's parser: every subcommand, its options and their defaults
(tests/test_cli_light.py)."""

from __future__ import annotations

import argparse
import re

from ..components import COMPONENTS
from ..fmus.options import FLAVORS, FMI_VERSIONS
from ..inputs.outputs import UsageError
from ..inputs.text import did_you_mean, one_line, prefix
from ..master.spec import DEFAULT_MAX_STEPS
from ..scenarios.scenario import shipped_scenarios
from .argtypes import _count, _non_negative, _positive
from .options import (
    add_dask,
    add_fmu_dir,
    add_fmu_options,
    add_format,
    add_json,
    add_no_plots,
    add_out,
    add_overwrite_option,
    add_scenario,
)

__all__ = ["UsageError", "build_parser"]


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

    b = sub.add_parser(
        "build",
        help="build our FMUs, one per registered component",
        description="Build our FMUs, one per component of the registry.",
    )
    add_out(b, "output folder (default: fmus, fmus/native for native, fmus/fmi3 and "
            "fmus/fmi3/native with --fmi 3)")  # fmt: skip
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
    add_scenario(r, f"TOML file, shipped name ({', '.join(shipped_scenarios())}) or .ssp/.ssd "
                 "file; default: default")  # fmt: skip
    add_out(r, "results folder, written straight into (default: out/<scenario>); results an "
            "earlier run made there with other settings are replaced, with a note naming them",
            metavar="DIR")  # fmt: skip
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
    add_no_plots(r, "skip the PNG plots and plots.html")
    add_format(r, "results file: results.csv (text) or results.parquet (binary float64, read "
               "by pandas and polars; needs pyarrow)")  # fmt: skip
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
    add_out(ob, "output folder", required=True)

    e = sub.add_parser(
        "export-ssp", help="write the system as an SSP archive (1.0; 2.0 for FMI 3.0 FMUs)"
    )
    e.add_argument("out", metavar="OUT", help="output .ssp file, in a folder that exists")
    add_scenario(e)
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
    add_scenario(xf)
    add_fmu_options(xf)

    rep = sub.add_parser("report", help="run every figure's scenario and write report.md")
    add_out(rep, "report folder", default="out/report")
    add_fmu_options(rep)
    rep.add_argument("--no-progress", action="store_true", help="the same as --quiet")
    add_no_plots(rep, "skip report.html (the PNGs stay: report.md shows them)")
    rep.add_argument("--roa-grid", default="7x5", metavar="NxM|none",
                     help="region-of-attraction grid: N glide angles x M speeds (default "
                     "7x5; none: skip the map)")  # fmt: skip
    add_dask(rep, "local Dask workers for the map")

    xp = sub.add_parser(
        "explore",
        help="write a page that runs the glider in the browser, live",
        description="Write one self-contained explore.html: the three FMUs' WebAssembly\n"
        "modules under a master in the page; every slider re-simulates the run.",
    )
    add_scenario(xp, "TOML file or shipped name; default: default")
    add_out(xp, "folder of explore.html (default: out/<scenario>-explore)", metavar="DIR")
    add_fmu_dir(xp, "native FMI 3 FMUs with their components (default: the per-user cache's, "
                "built if missing)")  # fmt: skip
    add_overwrite_option(xp)

    a = sub.add_parser("analyze", help="equilibrium, eigenvalues, stable K_c range")
    add_json(a, "one JSON object on stdout")
    a.add_argument("--from-fmu", action="store_true",
                   help="the continuous-time Jacobian from the plant FMU's directional "
                   "derivatives (of the --flavor and --fmi asked) instead of the model's "
                   "central differences")  # fmt: skip
    add_fmu_options(a, fmi=True)

    s = sub.add_parser("sweep", help="parameter sweep / Monte Carlo on Dask",
                       description=_SWEEP)  # fmt: skip
    add_scenario(s, "scenario (default: default)")
    s.add_argument("--param", action="append", default=[], metavar="INSTANCE.NAME=SPEC",
                   help="swept parameter (repeatable): 6,8,10 | 2:20:10 | uniform(-20%%,+20%%)"
                   " | normal(20%%)")  # fmt: skip
    s.add_argument("--samples", type=int, default=10, help="draws for random specs")
    s.add_argument("--seeds", type=int, default=None, help="noise seeds 0..N-1 per run")
    s.add_argument("--rng-seed", type=int, default=0, help="seed of the random draws")
    add_dask(s, "local worker processes")
    add_out(s, "results folder: one sweep's (the same sweep resumes there)", default="out/sweep")
    add_format(s, "format of the sweep's table (parquet needs pyarrow)")
    s.add_argument("--trajectories", action="store_true", help="keep each run's results CSV")
    s.add_argument("--stop-time", type=float, default=None, help="stop time, s")
    add_fmu_options(s)
    s.add_argument("--restart", action="store_true",
                   help="replace the results in --out (another sweep's too)")  # fmt: skip
    add_no_plots(s, "skip the PNG plots")
    s.add_argument("--dashboard", action="store_true", help="serve and print the Dask dashboard")

    v = sub.add_parser("verify", help="run the experiments an FMU carries (FMI-LS-REF), or the "
                       "verification kit", description=_VERIFY)  # fmt: skip
    if command in (None, "verify"):
        _verify_options(v)
    ae = sub.add_parser("add-experiments", help="write an FMI-LS-REF experiment into a copy "
                        "of your FMU, from a run of our loop around it")  # fmt: skip
    if command in (None, "add-experiments"):
        _add_experiments_options(ae)
    cm = sub.add_parser(
        "compare",
        help="your controller or estimator against ours, on the paper's benchmark set",
        description="The paper's benchmark set with the scenario's [fmus] component and with\n"
        "ours, on our master and plant: compare.md/.html/.csv, an overlay figure per case.\n"
        "Exit 0 when the runs complete, whatever the comparison says; 2 on bad input.",
    )
    add_scenario(cm, "TOML file whose [fmus] swaps the controller or the observer",
                 nargs=None, metavar="SCENARIO")  # fmt: skip
    add_out(cm, "output folder (default: out/<scenario>-compare)", metavar="DIR")
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


_SWEEP = """Run a parameter sweep or a Monte Carlo study on Dask.

Each --param INSTANCE.NAME=SPEC (repeatable) is a list (6,8,10), a range START:STOP:NUM
(NUM values, both ends included) or random draws around the nominal value,
uniform(-20%,+20%) or normal(20%) (absolute: uniform(LOW,HIGH), normal(SD)); lists and
ranges form a full grid. An interrupted sweep resumes where it stopped; a folder that
holds another sweep's results is refused."""

_VERIFY = """Run the FMI-LS-REF experiments an FMU carries (its files' checksums
first). Else (or with --kit): a controller or estimator gets the loop's checks
(interface, units, outputs in Initialization Mode, none one step late, the
default start settling), then the reference cases (counted for a port of our
laws only); a plant, or --case: the cases against the references. Exit 0 if
all counted pass, 1 if one failed or a file changed after the FMU was built,
2 on bad input, a missing interface or nothing that can run."""


def _verify_options(p: argparse.ArgumentParser) -> None:
    """The options of ``glider-cosim verify`` (and ``python -m glider_cosim.verify``)."""
    from ..verify.cases import COMPONENTS

    p.add_argument("fmu", nargs="?", default=None, help="the FMU to verify")
    p.add_argument(
        "--component",
        choices=tuple(COMPONENTS),
        default=None,
        help="plant, observer or controller (default: found from the variables)",
    )
    p.add_argument("--case", default=None, help="one case (default: every case)")
    p.add_argument("--kit", action="store_true",
                   help="run the verification kit's cases of our components instead of the "
                   "FMI-LS-REF experiments the FMU carries (implied by --component, --case, "
                   "--rtol, --atol)")  # fmt: skip
    p.add_argument(
        "--rtol",
        type=tolerance_arg,
        default=None,
        help="relative tolerance for every case (default: each case's)",
    )
    p.add_argument(
        "--atol",
        type=tolerance_arg,
        default=None,
        help="absolute tolerance for every case, SI units (default: each case's)",
    )
    add_json(p, "print the whole result as one JSON object (for CI systems) instead of the table")
    p.add_argument(
        "--write-references",
        action="store_true",
        help="rerun the cases on our FMUs and rewrite the shipped references",
    )
    p.add_argument(
        "--export",
        default=None,
        metavar="DIR",
        help="write the cases with our FMUs in the FMI Cross-Check layout",
    )
    add_fmu_dir(p, "our FMUs for --write-references/--export and the loop checks' closed loop, "
                "built if missing or stale (default: the per-user cache)")  # fmt: skip
    add_overwrite_option(p)


def _add_experiments_options(p: argparse.ArgumentParser) -> None:
    """The options of ``glider-cosim add-experiments``."""
    from ..fmus.lsref import ROLES

    p.description = (
        "Put FMU in the loop of a scenario (the instance its [fmus] table gives it, else\n"
        "the component whose interface it has), run the loop, and write a copy of FMU that\n"
        "carries an FMI-LS-REF experiment: its recorded inputs as stimuli, its outputs as\n"
        "references, the scenario's parameter values. FMU itself is never written over."
    )
    p.add_argument("fmu", metavar="FMU", help="your FMI 2.0 or 3.0 co-simulation FMU")
    p.add_argument("--from", dest="case", required=True, metavar="CASE",
                   help="a shipped scenario's name or a scenario file")  # fmt: skip
    add_out(p, "the new FMU (not FMU; an existing file only if glider-cosim wrote it)",
            required=True, metavar="NEW.fmu")  # fmt: skip
    p.add_argument("--role", default=ROLES[0], choices=ROLES,
                   help="the experiment's role (default: experiment, a smoke test)")  # fmt: skip
    add_fmu_dir(p, "our other FMUs of the loop (default: the per-user cache)")


def tolerance_arg(text: str) -> float:
    """An ``--rtol``/``--atol`` argument as a float (argparse's type)."""
    from ..inputs.text import quote
    from ..verify.cases import VerifyInputError
    from ..verify.compare import check_tolerance

    try:
        value = check_tolerance(text, "")
    except VerifyInputError:
        raise argparse.ArgumentTypeError(
            f"{quote(text)} is invalid: expected a finite number >= 0"
        ) from None
    assert value is not None
    return value


#: ``--quiet``'s help, on every command
QUIET_HELP = (
    "no progress on stderr (default: off, so every wait over 2 s shows what is being done "
    "and how far: a bar on a terminal, plain lines in a pipe, a file or CI); results, "
    "notes and errors still print"
)
