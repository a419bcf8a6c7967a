"""``itps-flow-safety``: a flow-matching policy beside DP, and the safety cost, in Maze2D (see :mod:`.suite`)."""
