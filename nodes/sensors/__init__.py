"""cosim sensors node."""
