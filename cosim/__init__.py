"""glider-cosim: passivity-based glide stabilisation of an underwater glider as FMI co-simulation
components, the master that runs them, and the studies of the paper
(the package layout: docs/explanation/code-layout.md)."""
