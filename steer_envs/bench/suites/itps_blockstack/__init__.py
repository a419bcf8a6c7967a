"""ITPS on BlockStack (thesis §2.3, Table 2.2): the skill data set of the random planner, built through the bench."""
