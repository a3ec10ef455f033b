"""The solve stage: a run's record (baker/run) -> trail -> body -> legs, and the prey, for every
exported frame in array operations (solve.py), giving the Trajectory (trajectory.py)."""
