"""cosim control node."""
