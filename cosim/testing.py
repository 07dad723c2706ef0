"""pytest helpers for users' own test suites.

.. code-block:: python

    from glider_cosim.testing import assert_matches_reference

    def test_my_controller_behaves_like_the_reference():
        assert_matches_reference("build/MyController.fmu", "controller", rtol=1e-4)
"""

from __future__ import annotations

from pathlib import Path

from .verify.compare import verify

__all__ = ["assert_matches_reference"]


def assert_matches_reference(
    fmu: str | Path,
    component: str | None = None,
    case: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
) -> None:
    """Run the verification kit's cases on ``fmu``; raise ``AssertionError`` on a failure.

    Cases that need variables the FMU lacks are skipped (the FMU needs at least the
    component's core interface, and one case must run); a pass says that the cases that
    ran matched, no more.

    Parameters
    ----------
    fmu : path
        An FMI 2.0 or 3.0 co-simulation FMU with at least the component's core interface.
    component : str, optional
        ``plant``, ``observer`` or ``controller`` (default: found from the variables).
    case : str, optional
        One case (default: every case of the component).
    rtol, atol : float, optional
        Tolerances for every case (default: each case's own, see the README).

    Raises
    ------
    AssertionError
        One line per failing case: the case, the worst variable, its value and the
        reference's at the time of the largest error, the error and the tolerance.
    glider_cosim.verify.VerifyInputError
        Bad input (not an FMU, the core interface missing, no case that can run, unknown
        case, bad tolerance).
    """
    __tracebackhide__ = True
    report = verify(fmu, component, case, rtol, atol)
    failed = [r for r in report.results if not r.passed]
    if failed:
        name = Path(fmu).name
        lines = [f"{len(failed)} of {len(report.results)} {report.component} cases fail:"]
        lines += [r.describe(name) for r in failed]
        raise AssertionError("\n".join(lines))
