"""World and robot descriptions loaded into MuJoCo: MJCF, USD and (next) URDF or xacro, and the
one robot model every description format produces (``descriptions.robot_model``).

This is the wing of cosim that loads MuJoCo and OpenUSD; ``plan/`` below it stays pure Python.
"""
