"""LTL: parser, automata, replanner, Spot backend."""
