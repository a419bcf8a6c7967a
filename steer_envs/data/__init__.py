"""Scripted experts (demonstration generators) and dataset writing/reading."""
