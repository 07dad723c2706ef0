"""Writing FMI-LS-REF folders: experiments, parameter sets and documents that travel
inside an FMU (``extra/org.fmi-standard.fmi-ls-ref/``); our FMUs' folders
(``python -m glider_cosim.verify.lsref_ours --write``, shipped in each component's
folder, ``src/<component>/lsref/``, and packed by every build,
:mod:`glider_cosim.fmus.lsref`).

The layered standard FMI-LS-REF (modelica/fmi-ls-ref, version 1.0.0-alpha.1) lists an
FMU's related files in ``extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml``, each
``<Related>`` with a ``source`` (relative to the manifest), a ``role`` and a MIME
``type``. Experiments are files in the MA-HS-Experiments format (modelica/ma-hs-
experiments, ``application/x-ma-hs-experiments``): ``<Experiment name tolerance>``
with a ``<TransientSimulation startTime stopTime stepSize>``, optional ``<Parameters>``
(an SSV file), ``<Stimuli>`` and ``<References>`` (CSV files).

What the standards leave open, and what glider-cosim writes and reads
(docs/how-to/verify-a-component.md, "FMUs that carry their own tests"):

- **CSV layout**: a header ``time,<variable>,...`` (variables by their names in the
  model description), then one row per time, numbers as Python's ``repr`` writes them
  (exact).
- **Stimuli** are held: each row's values are set from its time until the next row's
  time (sample and hold), at the communication points ``start + k * step``.
- **References** are compared at each of their rows' times, which are communication
  points; the outputs are read after the inputs of that point are set (so an output
  that depends directly on an input sees the input of the same row).
- **tolerance** ``tol`` (a number >= 0): a value passes if
  ``|y - y_ref| <= tol * (1 + |y_ref|)``, i.e. an absolute tolerance ``tol`` near zero
  and a relative one ``tol`` for large values. An experiment without one is compared
  at :data:`~glider_cosim.fmus.lsref.DEFAULT_TOLERANCE` (1e-6).
- **Checksums**: the standard's ``<Related>`` has no checksum attribute (fmi-ls-ref
  at ``baf43cc``), so each entry carries its file's SHA3-256 in its ``<Annotations>``:
  ``<Annotation type="org.glider-cosim.checksum"><gc:Checksum algorithm="SHA3-256"
  value="..."/></Annotation>`` (:mod:`glider_cosim.fmus.lsref`), valid by
  the standard's ``fmi3Annotation.xsd``.

Our three FMUs carry (:func:`write_folders`):

- ``smoke-test.exp`` (role ``experiment/smoke-test``): the component's reference case,
  ``src/<component>/reference_input.csv`` and ``reference_output.csv`` with its
  parameters (:mod:`glider_cosim.verify.reference`);
- ``validation.exp`` (``experiment/validation``): the paper's default start (Sec. 3.3,
  60 s), component level: the component's inputs recorded from a run of the loop as
  stimuli, its outputs as references, the scenario's values of its parameters
  (:func:`record_component`);
- ``parameters/<scenario>.ssv`` (``parameter``): each shipped scenario's values of the
  component's parameters that differ from its start values (the limit cycle at
  K_c = 6, the paper's PI and P gains, the tail angles, ...);
- ``README.md`` (``document``): the component's readme, its equations.
"""

from __future__ import annotations

import posixpath
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from ..fmus.lsref import (
    CHECKSUM_ALGORITHM,
    CHECKSUM_NS,
    CHECKSUM_TYPE,
    EXPERIMENTS_MIME,
    LSREF_DIR,
    MANIFEST,
    sha3,
)

LS_NAME = "org.fmi-standard.fmi-ls-ref"
LS_VERSION = "1.0.0-alpha.1"
#: fixed by the schema
LS_DESCRIPTION = "Layered Standard providing information on related files included in an FMU."
LS_NS = "http://fmi-standard.org/fmi-ls-manifest"
SSV_MIME = "application/x-ssp-parameter-set"
#: the tolerance of our FMUs' smoke test (the reference case: round-off only)
SMOKE_TOLERANCE = 1e-9
#: the tolerance of our FMUs' validation (the loop's values replayed: round-off only)
VALIDATION_TOLERANCE = 1e-9

ET.register_namespace("fmi-ls", LS_NS)
ET.register_namespace("gc", CHECKSUM_NS)


class LsrefError(ValueError):
    """An LS-REF manifest or experiment cannot be written or read (one line naming the
    file and what is wrong)."""


# ------------------------------------------------------------------ what is written
@dataclass
class Experiment:
    """One transient experiment: its settings, parameters, stimuli and references.

    ``stimuli``/``references``: (columns, rows), ``time`` first; ``parameters``: name ->
    value (float, int or bool), written as an SSV file when not empty.
    """

    name: str
    description: str
    start: float
    stop: float
    step: float
    tolerance: float
    references: tuple[list[str], np.ndarray]
    stimuli: tuple[list[str], np.ndarray] | None = None
    parameters: dict[str, Any] = field(default_factory=dict)


@dataclass
class Related:
    """One ``<Related>`` entry: its file (path relative to the manifest) and bytes."""

    source: str
    role: str
    type: str
    description: str
    data: bytes
    labels: tuple[tuple[str, str], ...] = ()


def table_bytes(columns: Sequence[str], data: np.ndarray) -> bytes:
    """A CSV table: header, then each number in its shortest exact form (``repr``)."""
    lines = [",".join(columns)]
    lines += [",".join(repr(float(v)) for v in row) for row in np.asarray(data, dtype=float)]
    return ("\n".join(lines) + "\n").encode()


def xml_bytes(root: ET.Element) -> bytes:
    """An XML document, indented, with its declaration (UTF-8)."""
    ET.indent(root, "  ")
    text = ET.tostring(root, "unicode")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + text.encode() + b"\n"


def ssv_bytes(name: str, values: Mapping[str, Any], types: Mapping[str, str]) -> bytes:
    """An SSV parameter set, ``version="1.0"`` with SSP 1.0's types (``Real``,
    ``Integer``, ``Boolean``), which SSP 2.0 keeps: one file for FMI 2.0 and 3.0 FMUs.

    ``types``: variable name -> its FMI type in the model description (``Real``,
    ``Float64``, ``Integer``, ``Int32``, ``Boolean``)."""
    from .ssp_common import as_ssp1_type, format_value, qname

    root = ET.Element(qname("ssv", "ParameterSet"), {"version": "1.0", "name": name})
    params = ET.SubElement(root, qname("ssv", "Parameters"))
    for var, value in values.items():
        kind = types.get(var)
        if kind is None or as_ssp1_type(kind) not in ("Real", "Integer", "Boolean"):
            raise LsrefError(
                f"parameter set {name!r}: {var!r} is not a Real, Integer or "
                "Boolean variable of the FMU"
            )
        p = ET.SubElement(params, qname("ssv", "Parameter"), {"name": var})
        ET.SubElement(p, qname("ssv", as_ssp1_type(kind)), {"value": format_value(value, kind)})
    return xml_bytes(root)


def experiments_bytes(
    name: str, description: str, experiments: Sequence[tuple[Experiment, dict]]
) -> bytes:
    """An MA-HS-Experiments file; each experiment with its files' names (``parameters``,
    ``stimuli``, ``references``: paths relative to this file)."""
    root = ET.Element("Experiments", {"name": name, "description": description})
    for ex, files in experiments:
        el = ET.SubElement(
            root,
            "Experiment",
            {
                "name": ex.name,
                "description": ex.description,
                "tolerance": repr(float(ex.tolerance)),
            },
        )
        ET.SubElement(
            el,
            "TransientSimulation",
            {
                "startTime": repr(float(ex.start)),
                "stopTime": repr(float(ex.stop)),
                "stepSize": repr(float(ex.step)),
            },
        )
        for tag, key, mime in (
            ("Parameters", "parameters", SSV_MIME),
            ("Stimuli", "stimuli", "text/csv"),
            ("References", "references", "text/csv"),
        ):
            if key in files:
                ET.SubElement(el, tag, {"type": mime, "source": files[key]})
    return xml_bytes(root)


def experiment_files(
    folder: str,
    experiments: Sequence[Experiment],
    types: Mapping[str, str],
    role: str,
    title: str,
    description: str,
) -> list[Related]:
    """The entries of an experiments file ``<folder>.exp`` and the files it names
    (``<folder>/<experiment>-parameters.ssv``, ``-stimuli.csv``, ``-references.csv``)."""
    out: list[Related] = []
    listed = []
    for ex in experiments:
        files = {}
        if ex.parameters:
            files["parameters"] = f"{folder}/{ex.name}-parameters.ssv"
            out.append(
                Related(
                    files["parameters"],
                    "parameter",
                    SSV_MIME,
                    f"parameters of the {title} experiment {ex.name!r}",
                    ssv_bytes(f"{folder}-{ex.name}", ex.parameters, types),
                    (("experiment", f"{folder}.exp#{ex.name}"),),
                )
            )
        if ex.stimuli is not None:
            files["stimuli"] = f"{folder}/{ex.name}-stimuli.csv"
            out.append(
                Related(
                    files["stimuli"],
                    "testcase",
                    "text/csv",
                    f"stimuli of the {title} experiment {ex.name!r} (held)",
                    table_bytes(*ex.stimuli),
                )
            )
        files["references"] = f"{folder}/{ex.name}-references.csv"
        out.append(
            Related(
                files["references"],
                "result",
                "text/csv",
                f"references of the {title} experiment {ex.name!r}",
                table_bytes(*ex.references),
            )
        )
        here = posixpath.dirname(f"{folder}.exp") or "."  # the .exp's own folder
        listed.append((ex, {k: posixpath.relpath(v, here) for k, v in files.items()}))
    exp = Related(
        f"{folder}.exp",
        role,
        EXPERIMENTS_MIME,
        description,
        experiments_bytes(title, description, listed),
    )
    return [exp, *out]


def manifest_bytes(related: Sequence[Related]) -> bytes:
    """The manifest listing ``related``, each with its SHA3-256 (:data:`CHECKSUM_TYPE`)."""
    ls = f"{{{LS_NS}}}"
    root = ET.Element(
        "fmiReferences",
        {
            f"{ls}fmi-ls-name": LS_NAME,
            f"{ls}fmi-ls-version": LS_VERSION,
            f"{ls}fmi-ls-description": LS_DESCRIPTION,
        },
    )
    for r in related:
        el = ET.SubElement(
            root,
            "Related",
            {"type": r.type, "source": r.source, "role": r.role, "description": r.description},
        )
        for label, value in r.labels:
            ET.SubElement(el, "Label", {"name": f"{label}:{value}"})
        note = ET.SubElement(
            ET.SubElement(el, "Annotations"), "Annotation", {"type": CHECKSUM_TYPE}
        )
        ET.SubElement(
            note,
            f"{{{CHECKSUM_NS}}}Checksum",
            {"algorithm": CHECKSUM_ALGORITHM, "value": sha3(r.data)},
        )
    return xml_bytes(root)


def zip_entries(related: Sequence[Related]) -> dict[str, bytes]:
    """Zip path -> bytes: the manifest and every file it lists."""
    out = {f"{LSREF_DIR}/{r.source}": r.data for r in related}
    out[MANIFEST] = manifest_bytes(related)
    return out
