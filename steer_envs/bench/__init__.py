"""steer-bench: the benchmark runner."""
