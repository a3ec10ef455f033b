"""The simulation: run (baker/run) then solve (baker/solve); loop.simulate is the entry."""
