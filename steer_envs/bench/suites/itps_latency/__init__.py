"""``itps-latency``: steering latency of the Maze2D DP on every acceleration path (see :mod:`.suite`)."""
