"""Real time and components outside the process: paced runs, UDP endpoints, onboard builds."""
