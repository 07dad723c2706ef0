"""The glider plant: dynamics, 10 ms tail servo and pitch sensor (model and FMU slave)."""
