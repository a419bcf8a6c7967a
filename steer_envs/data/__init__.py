"""Demonstrations and data sets: scripted experts, expert demos, GLiDE's counterfactual replays."""
