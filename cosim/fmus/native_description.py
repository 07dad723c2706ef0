"""The model description and ``sources/buildDescription.xml`` of a native FMU (``c``: a
:class:`glider_cosim.fmus.native.NativeComponent`), and what its generated variables header
declares besides the variables (C names, the directional derivatives' tables)."""

from __future__ import annotations

import tempfile
from typing import Any
from xml.etree import ElementTree as ET

from .files import package_version


def model_description(c: Any, sources: list[str], digest: str) -> bytes:
    """The Python slave's model description, for a native FMU: same variables, units and
    structure; a new GUID (from ``digest``, the FMI 2 build's
    :func:`glider_cosim.fmus.native.native_hash`), our generation tool, no execution
    tool, and ``<SourceFiles>``."""
    cls = c.slave_class()
    with tempfile.TemporaryDirectory(prefix="glider_native_") as tmp:
        slave = cls(instance_name="codegen", resources=tmp)
        root = slave.to_xml(
            {
                "needsExecutionTool": "false",
                "canHandleVariableCommunicationStepSize": "true",
                "canBeInstantiatedOnlyOncePerProcess": "false",
                "canGetAndSetFMUstate": "true",
                "canSerializeFMUstate": "true",
            }
        )
    import uuid  # here: a build's alone, not every run's start

    root.set(
        "guid",
        "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"glider-cosim/{c.name}/" + digest)) + "}",
    )
    root.set("generationTool", f"glider-cosim {package_version()} (native C99)")
    root.set("version", package_version())
    cs = root.find("CoSimulation")
    cs.set("needsExecutionTool", "false")
    cs.set("canGetAndSetFMUstate", "true")
    cs.set("canSerializeFMUstate", "true")
    for child in list(cs):
        cs.remove(child)
    files = ET.SubElement(cs, "SourceFiles")
    for name in sources:
        ET.SubElement(files, "File", name=name)
    ET.indent(root, "\t")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def build_description(c: Any, sources: list[str]) -> bytes:
    """``sources/buildDescription.xml`` (FMI 3.0 layout, allowed in FMI 2.0.4)."""
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    config = ET.SubElement(root, "BuildConfiguration", modelIdentifier=c.name)
    # contraction off (no fused multiply-add), as in the sources themselves (glider_fp.h)
    files = ET.SubElement(config, "SourceFileSet", language="C99",
                          compilerOptions="-ffp-contract=off")  # fmt: skip
    for name in sources:
        ET.SubElement(files, "SourceFile", name=name)
    ET.SubElement(config, "Library", name="m", description="libm (POSIX platforms)")
    ET.indent(root, "\t")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def c_name(name: str) -> str:
    """A variable's name as a C identifier: ``der(V)`` -> ``der_V``."""
    return name.replace("(", "_").replace(")", "")


def jacobian_lines(cls: type, up: str) -> list[str]:
    """``<MODEL>_JAC_ROW``, ``_JAC_COL``, ``_JAC_NROWS``, ``_JAC_NCOLS`` of the slave's
    directional derivatives (``glider_fmi.slave_base.GliderSlave._jacobian_tables``;
    NULL and 0 when it provides none)."""
    with tempfile.TemporaryDirectory(prefix="glider_native_") as tmp:
        tables = cls(instance_name="codegen", resources=tmp)._jacobian_tables()
    if tables is None:
        return [f"#define {up}_JAC_ROW NULL", f"#define {up}_JAC_COL NULL",
                f"#define {up}_JAC_NROWS 0", f"#define {up}_JAC_NCOLS 0"]  # fmt: skip
    rows, cols, nrows, ncols = tables
    return [
        "/* directional derivatives: each value reference's row and column (-1: none) */",
        f"static const int {up}_JAC_ROW[] = {{{', '.join(map(str, rows))}}};",
        f"static const int {up}_JAC_COL[] = {{{', '.join(map(str, cols))}}};",
        f"#define {up}_JAC_NROWS {nrows}",
        f"#define {up}_JAC_NCOLS {ncols}",
    ]
