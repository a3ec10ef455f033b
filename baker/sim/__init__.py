"""Fixed-step clock and the step loop."""
