"""tli-arm-scoop: LTL-DS soup scooping on the Panda arm (thesis robot experiment 1)."""
