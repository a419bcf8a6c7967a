"""Simulated users: sketchers, pointers and perturbers."""
