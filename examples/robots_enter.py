"""Robots that enter and leave a running swarm, from Python (docs/tutorials/robots-enter.md).

The seeds' ``spawn_robot(usd_path)`` and ``spawn_robot_swarm(count)`` as cosim events: each
robot enters at a tick with its own lidar and controller (the scenario's ``for_each: robot``
nodes), and ``delete`` takes one out again. The same events give one digest in-process and
multi-process.
"""

from orchestrator.api import delete, load, run, spawn_robot, spawn_robot_swarm

base = load("scenarios/swarm.yaml")
events = [
    spawn_robot("late", at="1s", start=(0.0, -0.4, 0.0), goal=(0.8, -0.4)),
    *spawn_robot_swarm(base, 2, at="600ms", region={"x": [-2.6, -1.4], "y": [-0.7, 0.7]},
                       goal_region={"x": [-2.6, -1.4], "y": [-0.7, 0.7]}),
    delete("swarm_1", at="2s"),
]
result = run(base, in_process=True, events=events, duration="3s", check=True)
print("robots in the world at the end:", int(result.metrics["robots"]))
print("late reached its goal:", result.metrics["late/arrived"] == 1.0)
print("digest", result.digest)
