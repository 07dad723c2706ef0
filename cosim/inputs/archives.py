"""Reading FMU and SSP files safely: regular files only, complete FMUs, bounded unpacking.

Nothing here loads a binary or runs FMU code: :func:`read_fmu` checks an FMU from its
zip directory and model description, :func:`safe_extract` unpacks an archive member by
member, refusing paths that leave the target folder and stopping at a total size.
"""

from __future__ import annotations

import os
import stat
import sys
import zipfile
import zlib
from pathlib import Path
from typing import Any

from .text import one_line, quote, shown_path

#: default limit of the bytes one archive may unpack to (``--max-extract-mb``)
DEFAULT_EXTRACT_LIMIT = 256 * 2**20
#: most members one archive may have
MAX_MEMBERS = 100_000
#: largest model description read (bytes)
MAX_MODEL_DESCRIPTION = 64 * 2**20
_limit = {"bytes": DEFAULT_EXTRACT_LIMIT}
_MAGIC = {"linux": (b"\x7fELF",), "win32": (b"MZ",),
          "darwin": (b"\xcf\xfa\xed\xfe", b"\xce\xfa\xed\xfe", b"\xca\xfe\xba\xbe")}  # fmt: skip
_ZIP_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError,
               OSError, ValueError, KeyError)  # fmt: skip


class InputFileError(ValueError):
    """An FMU, SSP or scenario file cannot be used; the message names it and why."""


def set_extract_limit(n_bytes: int) -> None:
    """Set the total size (bytes, > 0) an archive may unpack to, for this process."""
    if isinstance(n_bytes, bool) or not isinstance(n_bytes, int) or n_bytes <= 0:
        raise ValueError(f"extraction limit {quote(n_bytes)} is invalid: expected an integer > 0")
    _limit["bytes"] = n_bytes


def extract_limit() -> int:
    """The current extraction limit (bytes)."""
    return _limit["bytes"]


def _at(where: str | None) -> str:
    """``"WHERE: "``, the start of a message about the input at ``where`` (``""`` for
    None: the command's own argument, which the console's prefix names)."""
    return f"{where}: " if where else ""


def regular_file(path: str | Path, where: str | None, what: str = "file") -> Path:
    """``path`` if it is an existing regular file, else :class:`InputFileError`.

    Devices, FIFOs and folders are refused before anything is read from them.
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise InputFileError(f"{_at(where)}{what} {shown_path(p)} does not exist") from None
    except (OSError, ValueError) as err:
        reason = getattr(err, "strerror", None) or one_line(err)
        raise InputFileError(f"{_at(where)}cannot read {what} {shown_path(p)} ({reason})") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputFileError(
            f"{_at(where)}{what} {shown_path(p)} is not a regular file: expected a file on disk"
        )
    return p


def safe_extract(archive: str | Path, dest: Path, where: str, limit: int | None = None) -> None:
    """Unpack the zip ``archive`` into the folder ``dest``.

    Parameters
    ----------
    archive : path
        A regular zip file.
    dest : Path
        Existing target folder.
    where : str
        Prefix of error messages (the file or option).
    limit : int, optional
        Most bytes unpacked in total (default :func:`extract_limit`); the declared sizes
        are checked first and the bytes actually written while unpacking.

    Raises
    ------
    InputFileError
        Not a readable zip, corrupt data, a member outside ``dest``, too many members,
        or more than ``limit`` bytes.
    """
    limit = extract_limit() if limit is None else limit
    too_big = (
        f"{_at(where)}unpacks to more than {limit} bytes (the extraction limit, "
        "option --max-extract-mb)"
    )
    dest_r = dest.resolve()
    try:
        with zipfile.ZipFile(archive) as z:
            infos = z.infolist()
            if len(infos) > MAX_MEMBERS:
                raise InputFileError(f"{_at(where)}{len(infos)} members: more than {MAX_MEMBERS}")
            if sum(i.file_size for i in infos) > limit:
                raise InputFileError(too_big)
            for info in infos:
                target = (dest / info.filename).resolve()
                if info.filename.startswith(("/", "\\")) or not target.is_relative_to(dest_r):
                    raise InputFileError(
                        f"{_at(where)}archive member {quote(info.filename)} points outside it"
                    )
            written = 0
            for info in infos:
                target = dest / info.filename
                if info.is_dir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                with z.open(info) as src, open(target, "wb") as dst:
                    while chunk := src.read(1 << 20):
                        written += len(chunk)
                        if written > limit:
                            raise InputFileError(too_big)
                        dst.write(chunk)
    except InputFileError:
        raise
    except _ZIP_ERRORS as err:
        raise InputFileError(f"{_at(where)}not a readable zip archive ({one_line(err)})") from None


def _is_pythonfmu(md: Any, names: set[str]) -> bool:
    return "resources/slavemodule.txt" in names or str(md.generationTool or "").startswith(
        "PythonFMU"
    )


def _platform() -> tuple[str, str, str]:
    """This host's FMI 2 binaries folder (``linux64``, ``win64``, ``darwin64``), FMI 3
    platform tuple (``x86_64-linux``) and shared library suffix, as fmpy names them."""
    from glider_fmi.toolchain import host_machine

    system, arch = host_machine()
    system = system if system in ("windows", "darwin") else "linux"
    suffix = {"windows": ".dll", "darwin": ".dylib"}.get(system, ".so")
    fmi2 = "win" if system == "windows" else system
    if arch == "aarch64":
        return f"{fmi2}64", f"aarch64-{system}", suffix
    if sys.maxsize > 2**32:
        return f"{fmi2}64", f"x86_64-{system}", suffix
    return f"{fmi2}32", f"x86-{system}", suffix


#: this host's FMI 2 binaries folder, FMI 3 platform tuple and shared library suffix
FMI2_PLATFORM, FMI3_PLATFORM, LIBRARY_SUFFIX = _platform()


def binary_path(md: Any) -> str:
    """The binary a host on this platform loads from a co-simulation FMU, as fmpy finds
    it: ``binaries/<platform>/<model identifier><ext>`` (FMI 3: the platform tuple, such
    as ``x86_64-linux``; FMI 2: ``linux64``, ``win64``, ``darwin64``)."""
    folder = FMI3_PLATFORM if md.fmiVersion == "3.0" else FMI2_PLATFORM
    return f"binaries/{folder}/{md.coSimulation.modelIdentifier}{LIBRARY_SUFFIX}"


def _description(source: str, validate: bool) -> Any:
    """fmpy's ``read_model_description`` of the FMU file ``source``;
    fmpy's plain Exception (schema, model checks, XML) as :class:`InputFileError`'s
    reason, carried in a ``ValueError``."""
    from fmpy import read_model_description

    try:
        return read_model_description(source, validate=validate)
    except Exception as err:  # noqa: BLE001 - fmpy raises plain Exception for bad descriptions
        raise ValueError(one_line(err)) from None


def read_fmu(path: str | Path, where: str | None, schema: bool = True) -> Any:
    """Check that ``path`` is a complete FMI 2.0 or 3.0 co-simulation FMU; return its
    model description (fmpy's ``ModelDescription``, from ``fmpy.read_model_description``).

    Checked without loading anything: a regular zip file, ``modelDescription.xml``, FMI
    2.0 or 3.0 co-simulation, the binary for this platform (``binaries/<platform>/<model
    identifier><ext>``, FMI 3's platform tuple such as ``x86_64-linux`` for FMI 3, with
    the platform's executable header), and for a pythonfmu FMU
    ``resources/slavemodule.txt`` and the script it names (without them pythonfmu's
    binary crashes at instantiation).

    With ``schema`` (the default), fmpy validates the description against the FMI schema
    and runs its model checks, and a failure there is named by fmpy; the master leaves
    the validation out for the FMUs of its own cache, which glider-cosim built.

    Raises
    ------
    InputFileError
        What is missing or unreadable, after ``where``.
    """
    p = regular_file(path, where, "FMU")
    name = quote(p.name)
    try:
        with zipfile.ZipFile(p) as z:
            infos = {i.filename: i for i in z.infolist()}
            md_info = infos.get("modelDescription.xml")
            if md_info is None:
                raise InputFileError(f"{_at(where)}FMU {name} has no modelDescription.xml")
            if md_info.file_size > MAX_MODEL_DESCRIPTION:
                raise InputFileError(f"{_at(where)}FMU {name}: modelDescription.xml is too large")
            z.read(md_info)  # CRC and deflate data checked
            try:
                md = _description(str(p), schema)
            except ValueError as err:
                raise InputFileError(
                    f"{_at(where)}FMU {name} has no readable model description ({err})"
                ) from None
            if md.fmiVersion not in ("2.0", "3.0") or md.coSimulation is None:
                raise InputFileError(
                    f"{_at(where)}FMU {name} is not an FMI 2.0 or 3.0 co-simulation FMU"
                )
            binary = binary_path(md)
            if binary not in infos:
                raise InputFileError(
                    f"{_at(where)}FMU {name} has no binary for this platform ({quote(binary)})"
                )
            with z.open(binary) as f:
                head = f.read(4)
            magics = _MAGIC.get(sys.platform, ())
            if magics and not head.startswith(magics):
                raise InputFileError(
                    f"{_at(where)}FMU {name}: {quote(binary)} is not a shared library for this "
                    "platform"
                )
            if _is_pythonfmu(md, set(infos)):
                if "resources/slavemodule.txt" not in infos:
                    raise InputFileError(
                        f"{_at(where)}FMU {name} (pythonfmu) has no resources/slavemodule.txt"
                    )
                module = z.read("resources/slavemodule.txt")[:1000].decode("utf-8", "replace")
                module = module.strip()
                if not {f"resources/{module}.py", f"resources/{module}/__init__.py"} & set(infos):
                    raise InputFileError(
                        f"{_at(where)}FMU {name} (pythonfmu) has no script "
                        f"{quote(f'resources/{module}.py')}"
                    )
    except InputFileError:
        raise
    except _ZIP_ERRORS as err:
        reason = one_line(err)
        raise InputFileError(f"{_at(where)}FMU {name} is not a readable zip ({reason})") from None
    return md


def read_description(path: str | Path) -> Any:
    """The model description of the FMU file ``path`` (fmpy's ``read_model_description``,
    without schema validation; nothing else of the FMU is checked: :func:`read_fmu` checks
    a whole FMU).

    Raises
    ------
    InputFileError
        Not a readable zip, no ``modelDescription.xml``, or one that cannot be read.
    """
    name = quote(Path(path).name)
    try:
        with zipfile.ZipFile(path) as z:
            info = z.getinfo("modelDescription.xml")
            if info.file_size > MAX_MODEL_DESCRIPTION:
                raise InputFileError(f"FMU {name}: modelDescription.xml is too large")
            z.read(info)  # CRC and deflate data checked
    except _ZIP_ERRORS as err:
        raise InputFileError(f"FMU {name} is not a readable zip ({one_line(err)})") from None
    try:
        return _description(str(path), False)
    except ValueError as err:
        raise InputFileError(f"FMU {name} has no readable model description ({err})") from None


def confined(folder: Path, ref: str, where: str) -> Path:
    """The file ``ref`` (an SSP ``source``: relative, optionally ``file:``) inside
    ``folder``; :class:`InputFileError` if it is absolute, has another URI scheme, or
    leaves ``folder`` (``..``, symbolic links)."""
    rel = ref[len("file:") :] if ref.startswith("file:") else ref
    if rel.startswith("//"):
        rel = rel[2:]
    if (
        not rel
        or "\0" in rel
        or rel.startswith(("/", "\\"))
        or Path(rel).is_absolute()
        or (":" in rel.split("/", 1)[0])
    ):
        raise InputFileError(
            f"{_at(where)}source {quote(ref)} is invalid: expected a path relative to the SSP"
        )
    target = (folder / rel).resolve()
    if not target.is_relative_to(folder.resolve()):
        raise InputFileError(f"{_at(where)}source {quote(ref)} points outside the SSP")
    return target
