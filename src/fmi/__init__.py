"""glider_fmi: the FMI plumbing every glider slave shares and our FMI 2.0 runtime.

- :mod:`glider_fmi.slave_base`: the slaves' common base (variable tables, model
  description, validation, FMU state and its serialization);
- :mod:`glider_fmi.state_codec`: FMU state to bytes and back;
- ``fmi2_layer.c``: the FMI 2.0 co-simulation layer in C every FMU runs, over two back
  ends: ``backend_python.c`` (hosts a pythonfmu slave) and ``backend_native.c`` (a
  component's C model);
- :mod:`glider_fmi.compile`: compiles the runtime and records the Python it starts in
  hosts without one.
"""
