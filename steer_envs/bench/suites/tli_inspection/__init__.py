"""TLI inspection line (thesis appendix "Robot Experiment 2"): see :mod:`.suite`."""
