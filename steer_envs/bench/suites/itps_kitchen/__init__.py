"""ITPS on Kitchen (thesis §2.3, Table 2.3): the skill data set of the scripted expert, built through the bench."""
