"""Other tools' formats and hosts: SSP export and import, libcosim, the one-FMU export,
the host environment."""
