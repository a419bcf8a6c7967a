"""Helpers shared by every layer: command-line parsing, the env checker."""
