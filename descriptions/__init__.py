"""World and robot descriptions loaded into MuJoCo: MJCF, USD, URDF and xacro, and the
one robot model every description format produces (``descriptions.robot_model``), read once
from a world (``descriptions.robot_reader``) and given to every node that needs the robot.

This is the wing of cosim that loads MuJoCo and OpenUSD; ``plan/`` below it stays pure Python
and reads a world through ``plan.world_reader`` (``descriptions.load.load_scenario`` gives it
this wing's loader).

Every robot description format has one reader behind one registry, ``readers`` (the only
place a file's format is recognised); what a reader gives nodes is format-neutral: the robot
model and its TF and joint states (``robot_state``), which the plan hands each node that
needs the robot (``NodeConfig.robots``; a node's world check gets it too).

A URDF or xacro robot (docs/tutorials/own-robot.md): ``xacro_expand`` (xacro, ``$(find)``),
``packages`` (``package://``), ``urdf_parse`` (the document as data), ``urdf_to_mjcf`` (the
faithful MjSpec), ``urdf`` (actuators, sensors and its robot model: ``load_urdf``),
``urdf_geometry`` (wheel radius, separation, footprint), ``urdf_robot`` (a scenario's
settings, once per process) and ``describe`` (``cosim-describe``).

A robot described in USD (docs/how-to/usd-robots.md): ``usd_stage_robot`` (the stage read
with UsdPhysics into links, frames and cameras, in Isaac Sim's importer, urdf-usd-converter's
and mujoco-usd-converter's layouts; its joints and drives by ``usd_joints``, its shapes by
``usd_geometry``, values and poses off prims by ``usd_prims``) and ``usd_robot`` (written as
the URDF it is equivalent to and loaded by ``load_urdf``: ``load_usd``).
"""
