"""Our model description reader (``glider_cosim.inputs.description``, issue 48) against
fmpy's ``read_model_description`` on hand-made FMI 2.0 and 3.0 descriptions: every
attribute glider-cosim reads is the same, and what fmpy refuses ours refuses too, in one
line. ``tests/integration/test_description_fmus.py`` compares them on the project's FMUs."""

from __future__ import annotations

import pytest
from fmpy import read_model_description
from md_summary import summary

from glider_cosim.inputs.description import ModelDescriptionError, parse_model_description

FMI2 = b"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Probe" guid="{1234}" description="a probe"
  generationTool="hand" variableNamingConvention="structured" numberOfEventIndicators="0"
  author="me" version="1.2" copyright="none" license="MIT"
  generationDateAndTime="2026-01-01T00:00:00Z">
  <CoSimulation modelIdentifier="Probe" canHandleVariableCommunicationStepSize="true"
    canGetAndSetFMUstate="1" canSerializeFMUstate="false" providesDirectionalDerivative="true"
    maxOutputDerivativeOrder="2" canNotUseMemoryManagementFunctions="true"/>
  <UnitDefinitions>
    <Unit name="rad"><BaseUnit rad="1"/><DisplayUnit name="deg" factor="57.29577951308232"/></Unit>
    <Unit name="degC"><BaseUnit K="1" offset="273.15"/></Unit>
    <Unit name="m/s"><BaseUnit m="1" s="-1"/></Unit>
    <Unit name="none"/>
  </UnitDefinitions>
  <TypeDefinitions>
    <SimpleType name="Angle">
      <Real quantity="Angle" unit="rad" displayUnit="deg" min="-3.2" max="3.2"/></SimpleType>
    <SimpleType name="Mode"><Enumeration><Item name="off" value="0"/>
      <Item name="on" value="1" description="running"/></Enumeration></SimpleType>
  </TypeDefinitions>
  <DefaultExperiment startTime="0" stopTime="60" stepSize="0.02"/>
  <ModelVariables>
    <ScalarVariable name="theta" valueReference="0" causality="output">
      <Real declaredType="Angle"/></ScalarVariable>
    <ScalarVariable name="omega" valueReference="1" causality="local" initial="exact">
      <Real start="0.5" unit="rad" nominal="2" unbounded="true"/></ScalarVariable>
    <ScalarVariable name="der(theta)" valueReference="2">
      <Real derivative="1"/></ScalarVariable>
    <ScalarVariable name="u" valueReference="3" causality="input" description="the input">
      <Real start="0.2" unit="m/s" min="0" max="1"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="4" causality="parameter" variability="fixed">
      <Integer start="3" min="1" max="9"/></ScalarVariable>
    <ScalarVariable name="on" valueReference="5" causality="parameter" variability="tunable">
      <Boolean start="true"/></ScalarVariable>
    <ScalarVariable name="label" valueReference="6" causality="parameter" variability="fixed">
      <String start="hi"/></ScalarVariable>
    <ScalarVariable name="mode" valueReference="7" causality="output" variability="discrete">
      <Enumeration declaredType="Mode"/></ScalarVariable>
    <ScalarVariable name="k" valueReference="8" causality="output" variability="constant">
      <Real start="1.5"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="9" causality="output">
      <Real/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs>
      <Unknown index="1" dependencies="2 4" dependenciesKind="fixed dependent"/>
      <Unknown index="8" dependencies=""/>
      <Unknown index="9"/>
      <Unknown index="10" dependencies="4"/>
    </Outputs>
    <Derivatives><Unknown index="3" dependencies="2"/></Derivatives>
    <InitialUnknowns>
      <Unknown index="1" dependencies="4"/>
      <Unknown index="3"/>
      <Unknown index="8" dependencies=""/>
      <Unknown index="10" dependencies="4 5"/>
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""

FMI3 = b"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Probe3" instantiationToken="{abcd}"
  generationTool="hand" variableNamingConvention="flat">
  <CoSimulation modelIdentifier="Probe3" canGetAndSetFMUState="true" canSerializeFMUState="true"
    canHandleVariableCommunicationStepSize="true" hasEventMode="false"/>
  <UnitDefinitions>
    <Unit name="rad"><BaseUnit rad="1"/><DisplayUnit name="deg" factor="57.29577951308232"/></Unit>
  </UnitDefinitions>
  <TypeDefinitions>
    <Float64Type name="Angle" unit="rad" min="-4"/>
    <Int32Type name="Count" min="0"/>
  </TypeDefinitions>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="theta" valueReference="1" causality="output" declaredType="Angle">
      <Alias name="pitch" description="the same angle" displayUnit="deg"/>
    </Float64>
    <Float64 name="u" valueReference="2" causality="input" start="0.25" unit="rad"/>
    <Int32 name="n" valueReference="3" causality="parameter" variability="fixed" start="4"
      declaredType="Count"/>
    <Boolean name="on" valueReference="4" causality="parameter" variability="tunable"
      start="false"/>
    <Float64 name="x" valueReference="5" causality="local" initial="exact" start="0"/>
    <Float64 name="der(x)" valueReference="6" causality="local" derivative="5"/>
    <Int32 name="count" valueReference="7" causality="output"/>
    <UInt8 name="b" valueReference="8" causality="parameter" variability="fixed" start="3"
      min="1"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="1" dependencies="2 3" dependenciesKind="dependent fixed"/>
    <Output valueReference="7" dependencies=""/>
    <ContinuousStateDerivative valueReference="6"/>
    <InitialUnknown valueReference="1" dependencies="3"/>
    <InitialUnknown valueReference="7"/>
  </ModelStructure>
</fmiModelDescription>
"""


def fmpy_reads(tmp_path, data: bytes):
    path = tmp_path / "modelDescription.xml"
    path.write_bytes(data)
    return read_model_description(str(path))


@pytest.mark.parametrize("data", [FMI2, FMI3], ids=["fmi2", "fmi3"])
def test_every_attribute_is_the_one_fmpy_reads(tmp_path, data):
    ours, theirs = summary(parse_model_description(data)), summary(fmpy_reads(tmp_path, data))
    assert ours == theirs
    # the cases the comparison covers are really in it
    variables = {v[0]: v for v in ours["variables"]}
    assert len(variables) == 10
    assert [o[1] for o in ours["outputs"]][:2] == ([["omega", "u"], []] if data is FMI2
                                                  else [["u", "n"], []])  # fmt: skip


def test_the_defaults_are_fmis():
    md = parse_model_description(FMI2)
    v = {x.name: x for x in md.modelVariables}
    assert (v["der(theta)"].causality, v["der(theta)"].variability, v["der(theta)"].initial) == (
        "local", "continuous", "calculated")  # fmt: skip
    assert v["der(theta)"].derivative is v["theta"] and v["theta"].declaredType.unit == "rad"
    assert (v["u"].initial, v["n"].initial, v["k"].initial) == ("exact", "exact", "exact")
    assert md.outputs[2].dependencies is None and md.outputs[1].dependencies == []
    cs = md.coSimulation
    assert cs.canGetAndSetFMUstate is True and cs.maxOutputDerivativeOrder == 2
    md3 = parse_model_description(FMI3)
    v3 = {x.name: x for x in md3.modelVariables}
    assert md3.guid == md3.instantiationToken == "{abcd}"
    assert (v3["pitch"].alias, v3["pitch"].valueReference, v3["pitch"].displayUnit) == (
        v3["theta"], 1, "deg")  # fmt: skip
    assert (v3["n"].variability, v3["count"].variability, v3["x"].variability) == (
        "fixed", "discrete", "continuous")  # fmt: skip


def _edit(data: bytes, old: bytes, new: bytes) -> bytes:
    assert old in data, old
    return data.replace(old, new, 1)


MALFORMED = {
    "not XML": (b"<fmi", b"not well-formed XML"),
    "another root": (b"<?xml version='1.0'?><foo fmiVersion='2.0'/>", b"root element is <foo>"),
    "FMI 1.0": (_edit(FMI2, b'fmiVersion="2.0"', b'fmiVersion="1.0"'), b"fmiVersion '1.0'"),
    "no version": (_edit(FMI2, b'fmiVersion="2.0" ', b""), b"fmiVersion ''"),
    "no value reference": (_edit(FMI2, b'valueReference="3" ', b""), b"'u' has no valueReference"),
    "bad value reference": (_edit(FMI2, b'valueReference="3"', b'valueReference="x"'),
                            b"'u' valueReference = 'x' is not a number"),
    "no type element": (_edit(FMI2, b"<Real/></ScalarVariable>", b"</ScalarVariable>"),
                        b"'y' has no type element"),
    "undefined type": (_edit(FMI2, b'declaredType="Angle"', b'declaredType="Nope"'),
                       b"declaredType 'Nope', not defined"),
    "illegal combination": (_edit(FMI2, b'causality="input" description',
                                  b'causality="input" variability="constant" description'),
                            b"illegal combination of causality='input'"),
    "index out of range": (_edit(FMI2, b'<Unknown index="9"/>', b'<Unknown index="99"/>'),
                           b"index 99: out of range"),
    "dependency out of range": (_edit(FMI2, b'dependencies="2 4"', b'dependencies="2 40"'),
                                b"index 40: out of range"),
    "no ModelVariables": (FMI2[: FMI2.index(b"<ModelVariables>")] + b"</fmiModelDescription>",
                          b"no ModelVariables element"),
    "FMI 3 unknown value reference": (_edit(FMI3, b'<Output valueReference="7"',
                                            b'<Output valueReference="70"'),
                                      b"value reference 70: no variable has it"),
}  # fmt: skip


@pytest.mark.parametrize("case", MALFORMED)
def test_what_fmpy_refuses_ours_refuses_in_one_line(tmp_path, case):
    data, message = MALFORMED[case]
    with pytest.raises(Exception):  # noqa: B017 - fmpy raises plain Exception, and others
        fmpy_reads(tmp_path, data)
    with pytest.raises(ModelDescriptionError) as err:
        parse_model_description(data)
    assert message.decode() in str(err.value) and "\n" not in str(err.value)
