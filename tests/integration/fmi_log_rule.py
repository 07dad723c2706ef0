"""FMI's '#' rule for log messages, read as FMI Library reads them.

FMI 2.0 section 2.1.5: in a message, ``#<type><vr>#`` (type ``r``, ``i``, ``b`` or ``s``,
then the value reference's digits) names a variable and a literal ``#`` is written
``##``. FMI 3.0 keeps the rule with ``#<vr>#`` (no type character). FMI Library expands
the references and warns ("Expected type specification character 'r', 'i', 'b' or 's'",
"Expected value reference", "Expected terminating '#'") on anything else.
"""

from __future__ import annotations

import re


class FmiMessageError(ValueError):
    """A message that breaks the '#' rule: where, and what FMI Library would say."""


_REFERENCE = {2: re.compile(r"#([ribs])(\d+)#"), 3: re.compile(r"#(\d+)#")}


def parse_fmi_message(text: str, fmi: int) -> tuple[str, list[str]]:
    """A logged message read by the rule: (its text with ``##`` as ``#`` and each
    reference as ``{ref}``, the references found).

    Raises
    ------
    FmiMessageError
        A ``#`` that is neither ``##`` nor a whole reference of the FMI version.
    """
    out: list[str] = []
    refs: list[str] = []
    i = 0
    while i < len(text):
        c = text[i]
        if c != "#":
            out.append(c)
            i += 1
            continue
        if text.startswith("##", i):
            out.append("#")
            i += 2
            continue
        m = _REFERENCE[fmi].match(text, i)
        if m is None:
            expected = "'r', 'i', 'b' or 's' then digits" if fmi == 2 else "digits"
            raise FmiMessageError(
                f"'#' at {i} of {text!r} is neither '##' nor a reference: expected {expected} "
                "and a terminating '#'"
            )
        refs.append(m.group(0))
        out.append("{ref}")
        i = m.end()
    return "".join(out), refs
