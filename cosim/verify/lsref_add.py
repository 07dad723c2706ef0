"""``glider-cosim add-experiments FMU --from CASE --out NEW.fmu``: an FMI-LS-REF experiment
written into a copy of a user's FMU, from a run of our loop around it.

The FMU takes its place in the loop of ``CASE`` (a shipped scenario, or a scenario file;
the instance its ``[fmus]`` table gives it, else the component whose inputs and outputs
it has). The loop runs with our master; the FMU's inputs are recorded as the stimuli and
its outputs as the references (:func:`glider_cosim.verify.lsref_ours.record_component`, which
checks that the FMU alone on these stimuli reproduces them), with the values the
scenario gives its parameters as an SSV set. The new FMU is the user's, byte for byte in
every file, plus the experiment's files in ``extra/org.fmi-standard.fmi-ls-ref/`` and
the manifest (entries it carried before are kept).

The user's FMU is never written over: an ``--out`` that is the input, or an existing file
glider-cosim did not write there (the folder's record ``.glider-cosim-fmus.json``), is
refused.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from ..fmus import lsref as packed
from ..fmus import record
from ..fmus.files import file_sha256, replacing
from ..fmus.lsref import ROLES
from ..inputs.text import quote
from ..interop import lsref_write as lw
from .lsref_ours import record_component


class AddExperimentsError(ValueError):
    """The experiment cannot be added (one line naming the file or option and why)."""


def _check_out(fmu: Path, out: Path) -> None:
    """Refuse an ``out`` that is ``fmu`` or an existing file glider-cosim did not write."""
    if out.suffix.lower() != ".fmu":
        raise AddExperimentsError(f"--out {quote(str(out))} is invalid: expected a .fmu file")
    if out.resolve() == fmu.resolve():
        raise AddExperimentsError(
            f"--out {quote(str(out))} is the FMU itself: the user's FMU is never written "
            "over; give another file"
        )
    if not out.parent.is_dir():
        raise AddExperimentsError(f"--out {quote(str(out))}: its folder does not exist")
    if out.exists():
        try:
            rec = record.read_record(out.parent, "--out") or {}
        except record.FmuFolderError:
            rec = {}
        entry = rec.get(out.name)
        if entry is None or entry.get("sha256") != file_sha256(out):
            raise AddExperimentsError(
                f"--out {quote(str(out))} exists and is not a file glider-cosim wrote there: "
                "it is not written over; give another file"
            )


def _instance(scenario, fmu: Path, md) -> str:
    """The instance of ``scenario`` the FMU takes: the one its ``[fmus]`` table gives
    it, else the component whose inputs and outputs the FMU has."""
    from .compare import detect_component

    for inst, path in scenario.fmus.items():
        try:
            if Path(path).resolve() == fmu.resolve():
                return inst
        except OSError:
            continue
    return detect_component(md)


def merged_manifest(old: bytes | None, related: list[lw.Related]) -> bytes:
    """The manifest ``old`` (None: none) with ``related`` appended, each with its
    checksum; the entries it had are kept as they are."""
    new = ET.fromstring(lw.manifest_bytes(related))
    if old is None:
        return lw.xml_bytes(new)
    try:
        root = ET.fromstring(old)
    except ET.ParseError as err:
        raise AddExperimentsError(f"{packed.MANIFEST}: not valid XML ({err})") from None
    if root.tag != "fmiReferences":
        raise AddExperimentsError(f"{packed.MANIFEST}: the root is not <fmiReferences>")
    # <Annotations> of the manifest come after every <Related>
    tail = [el for el in root if el.tag != "Related"]
    for el in tail:
        root.remove(el)
    for el in new.findall("Related"):
        root.append(el)
    for el in tail:
        root.append(el)
    return lw.xml_bytes(root)


def add_experiments(
    fmu: str | Path,
    case: str | Path,
    out: str | Path,
    role: str = "experiment",
    fmu_dir: str | Path | None = None,
) -> Path:
    """Write ``out``: ``fmu`` with an LS-REF experiment recorded from ``case``'s loop.

    Parameters
    ----------
    fmu : path
        The user's FMI 2.0 or 3.0 co-simulation FMU, with the inputs and outputs of one
        of our components (plant, observer, controller).
    case : str or path
        A shipped scenario's name or a scenario file.
    out : path
        The new ``.fmu`` (never ``fmu``; an existing file only if glider-cosim wrote it).
    role : str
        The experiment's role (:data:`ROLES`).
    fmu_dir : path, optional
        Our other FMUs of the loop (default: the per-user cache, built if missing).

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    AddExperimentsError, ScenarioError, VerifyInputError
        Bad input (one line); also when the FMU alone does not reproduce the outputs it
        had in the loop (then no experiment can be written for it).
    """
    from ..fmus.folders import prepare_fmus
    from ..scenarios.scenario import load_scenario
    from .run import open_fmu

    fmu, out = Path(fmu), Path(out)
    if role not in ROLES:
        raise AddExperimentsError(f"role {quote(role)} is invalid: expected one of "
                                  f"{', '.join(ROLES)}")  # fmt: skip
    md = open_fmu(fmu)
    _check_out(fmu, out)
    sc = load_scenario(case)
    inst = _instance(sc, fmu, md)
    sc.fmus[inst] = str(fmu.resolve())
    ours = prepare_fmus(fmu_dir, None, skip=())
    try:
        ex = record_component(sc, inst, ours)
    except lw.LsrefError as err:
        raise AddExperimentsError(str(err)) from None
    ex.description = (f"{md.modelName} as the {inst} in the loop of scenario {sc.name!r} "
                      "(glider-cosim add-experiments)")  # fmt: skip
    types = {v.name: v.type for v in md.modelVariables}
    folder = f"experiments/{sc.name}"
    title = f"{md.modelName} {sc.name}"
    what = f"{md.modelName} in the loop of scenario {sc.name!r}"
    related = lw.experiment_files(folder, [ex], types, role, title, what)
    return write_copy(fmu, out, related)


def write_copy(fmu: Path, out: Path, related: list[lw.Related]) -> Path:
    """Write ``out``: every file of ``fmu`` as it is, plus ``related`` in its LS-REF folder
    and the manifest listing them (its old entries kept); ``out`` is recorded as written
    by glider-cosim in its folder's record. Refused as :func:`add_experiments` says."""
    _check_out(fmu, out)
    with zipfile.ZipFile(fmu) as src:
        names = set(src.namelist())
        clash = [f"{packed.LSREF_DIR}/{r.source}" for r in related
                 if f"{packed.LSREF_DIR}/{r.source}" in names]  # fmt: skip
        if clash:
            raise AddExperimentsError(f"FMU {quote(fmu.name)} already has {clash[0]}: "
                                      "give the experiment another name")  # fmt: skip
        old = src.read(packed.MANIFEST) if packed.MANIFEST in names else None
        manifest = merged_manifest(old, related)
        with record.locked(out.parent):
            _check_out(fmu, out)  # again, under the folder's lock
            with replacing(out) as part, zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as dst:
                for item in src.infolist():
                    if item.filename != packed.MANIFEST:
                        dst.writestr(item, src.read(item))
                for r in related:
                    dst.writestr(f"{packed.LSREF_DIR}/{r.source}", r.data)
                dst.writestr(packed.MANIFEST, manifest)
            try:
                rec = record.read_record(out.parent, "--out") or {}
            except record.FmuFolderError:
                rec = {}
            rec[out.name] = {"sha256": file_sha256(out)}
            record.write_record(out.parent, rec)
    return out
