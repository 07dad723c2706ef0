"""The controller: passivity-based, P, PI and open-loop laws (model and FMU slave)."""
