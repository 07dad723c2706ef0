"""Studies of the paper: analysis, the report and its figures, region of attraction, held tail."""
