"""glider_fmi: the FMI plumbing every glider slave shares and our FMI 2.0 runtime.

- :mod:`glider_fmi.slave_base`: the slaves' common base (variable tables, model
  description, validation, FMU state and its serialization);
- :mod:`glider_fmi.state_codec`: FMU state to bytes and back;
- ``runtime.c``: the FMI 2.0 co-simulation runtime in C that hosts a pythonfmu slave
  inside each FMU (``binaries/linux64/<model>.so``);
- :mod:`glider_fmi.compile`: compiles the runtime and records the Python it starts in
  hosts without one.
"""
