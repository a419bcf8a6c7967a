"""tli-color-tracing: LTL-DS under the three color-tracing replanning automata (thesis robot experiment 3)."""
