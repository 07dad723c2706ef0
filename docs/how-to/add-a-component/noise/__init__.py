"""A sensor-noise block between the plant's pitch sensor and the observer: a fourth
component of the loop (docs/how-to/add-a-component.md)."""
