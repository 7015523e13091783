"""World and robot descriptions loaded into MuJoCo: MJCF, USD and (next) URDF or xacro, and the
one robot model every description format produces (``descriptions.robot_model``), read once
from a world (``descriptions.robot_reader``) and given to every node that needs the robot.

This is the wing of cosim that loads MuJoCo and OpenUSD; ``plan/`` below it stays pure Python
and reads a world through ``plan.world_reader`` (``descriptions.load.load_scenario`` gives it
this wing's loader).
"""
