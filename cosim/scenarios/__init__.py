"""Scenarios: the shipped TOML files, their parser, overrides and the system they describe."""
