"""The model description and ``sources/buildDescription.xml`` of a native FMU (``c``: a
:class:`glider_cosim.fmus.native.NativeComponent`)."""

from __future__ import annotations

import tempfile
import uuid
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
