"""cosim sensors node: lidar and camera rendered from the physics state."""
