"""SSP files written with the standard's prefixes, whatever else the process imported."""

from __future__ import annotations

import subprocess
import sys

import pytest

SCRIPT = """
from xml.etree import ElementTree as ET
import glider_cosim.interop.{module} as m
from glider_cosim.interop.ssp_common import NS, OSP_MD_NS, qname
root = ET.Element(qname("ssd", "SystemStructureDescription"))
for prefix in NS:
    ET.SubElement(root, qname(prefix, "X"))
ET.SubElement(root, "{{" + OSP_MD_NS + "}}OspModelDescription")
print(ET.tostring(root).decode())
"""


@pytest.mark.parametrize("module", ["ssp_export", "ssp_import"])
def test_the_export_alone_writes_ssd_prefixes_not_ns0(module):
    """The prefixes are registered where both the export and the import take their names
    from (the export alone once wrote ``ns0:`` unless the import had been loaded)."""
    p = subprocess.run([sys.executable, "-c", SCRIPT.format(module=module)],
                       capture_output=True, text=True, timeout=60, check=True)  # fmt: skip
    text = p.stdout
    assert text.startswith("<ssd:SystemStructureDescription "), text
    for prefix in ("ssd", "ssc", "ssv", "osp", "gcosp"):
        assert f"<{prefix}:" in text, prefix
    assert "ns0" not in text
