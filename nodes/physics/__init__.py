"""cosim physics node."""
