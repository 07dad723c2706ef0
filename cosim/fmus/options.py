"""The choices of the options that pick our FMUs (``--flavor``, ``--fmi``): the flavors
and FMI versions we build (the options themselves: :mod:`glider_cosim.cli.options`)."""

from __future__ import annotations

#: the flavors of our FMUs: the Python reference (default) and the native C99 build
FLAVORS = ("python", "native")
#: what ``run --flavor`` also takes: the native FMI 3.0 FMUs' WebAssembly components,
#: run by wasmtime (FMI-LS-WASM)
WASM_FLAVOR = "wasm"
#: the FMI versions we build (``--fmi``)
FMI_VERSIONS = (2, 3)
