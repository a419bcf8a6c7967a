"""TLI re-tasking on Cooking-v0 (thesis appendix "Generalization Results"): see :mod:`.suite`."""
