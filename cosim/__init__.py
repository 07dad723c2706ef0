"""glider-cosim: passivity-based glide stabilisation of an underwater glider as FMI co-simulation
components, the master that runs them, and the studies of the paper
(the package layout: docs/explanation/code-layout.md)."""

#: the distribution's version (pyproject.toml reads it from here: one place)
__version__ = "0.5.0"
