"""cosim control node: the grid planner, the path follower and recovery."""
