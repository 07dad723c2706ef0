"""Building the FMUs: Python and native flavors, FMI 2 and 3, OSP-IS descriptions, the cache."""
