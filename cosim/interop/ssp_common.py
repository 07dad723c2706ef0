"""What the SSP export and import share: namespaces, annotation types, value formats."""

from __future__ import annotations

from typing import Any
from xml.etree import ElementTree as ET

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}

#: the SSD versions read (SSP 2.0 keeps SSP 1.0's namespaces and adds FMI 3's types)
SSD_VERSIONS = ("1.0", "2.0")


OMS_ANNOTATION_TYPE = "org.openmodelica"


OSP_ANNOTATION_TYPE = "com.opensimulationplatform"


#: our annotation on a component naming its OSP-IS model description in ``resources/``
OSP_MD_ANNOTATION_TYPE = "org.glider-cosim.osp-model-description"


OSP_MD_NS = "urn:glider-cosim:osp-model-description"


# the prefixes ElementTree writes (ssd:, ssc:, ...; gcosp: for ours) instead of ns0:,
# registered where both the export and the import take their names from
for _prefix, _uri in (*NS.items(), ("gcosp", OSP_MD_NS)):
    ET.register_namespace(_prefix, _uri)


FMU_MIME = "application/x-fmu-sharedlibrary"


VALUE_TYPES = ("Real", "Integer", "Boolean")


#: SSP 2.0's FMI 3 types as the SSP 1.0 ones our FMUs' variables are compared with
SSP2_TYPE_AS_SSP1 = {"Float64": "Real", "Int32": "Integer"}


def as_ssp1_type(tag: str) -> str:
    """An SSP 1.0 or 2.0 type name (``Real``/``Float64``, ``Integer``/``Int32``,
    ``Boolean``, ...) as SSP 1.0's (FMI 2's) name of the same type."""
    return SSP2_TYPE_AS_SSP1.get(tag, tag)


def qname(prefix: str, tag: str) -> str:
    """An SSP element or attribute name in ElementTree's ``{namespace}tag`` form."""
    return f"{{{NS[prefix]}}}{tag}"


def local_name(tag: str) -> str:
    """A tag without its ``{namespace}``."""
    return tag.rsplit("}", 1)[-1]


def format_value(value: Any, type_: str) -> str:
    """A parameter value as SSP text for its type (``Real``/``Float64``,
    ``Integer``/``Int32``, ``Boolean``)."""
    type_ = as_ssp1_type(type_)
    if type_ == "Real":
        return repr(float(value))
    if type_ == "Boolean":
        return "true" if bool(value) else "false"
    return str(int(value))


def as_fmi2_types(md: Any) -> Any:
    """An FMI 3.0 model description's Float64/Int32 variables as SSP 1.0's Real/Integer
    (the types an FMI 2.0 one declares); an FMI 2.0 one as it is."""
    from ..master.fmi3 import TYPE_AS_FMI2

    if str(md.fmiVersion).startswith("3"):
        for v in md.modelVariables:
            v.type = TYPE_AS_FMI2.get(v.type, v.type)
    return md
