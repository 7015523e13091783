"""Which cosim nodes serve their parameters as ROS 2 nodes: every one in a run of up to
PARAMETER_NODES_MAX nodes; above, the world's nodes and the first robot's copy of each
robot's node (each served node is eight services of the orchestrator's)."""

from __future__ import annotations

from bench.swarm import scenario as swarm_scenario
from descriptions.load import load_scenario
from orchestrator.ros_surface.param_server import PARAMETER_NODES_MAX, served


def test_a_large_swarm_serves_the_first_robots_parameters_and_a_small_one_every_nodes(
        tmp_path):
    small = load_scenario(swarm_scenario(4, 0.1, tmp_path))
    assert [p.name for p in served(small)] == list(small.nodes)
    n = PARAMETER_NODES_MAX // 2 + 1  # 2 nodes a robot and the world's: over the limit
    large = load_scenario(swarm_scenario(n, 0.1, tmp_path))
    assert len(large.nodes) > PARAMETER_NODES_MAX
    first = sorted(p.name for p in large.nodes.values() if "@" in p.name)[0].partition("@")[2]
    assert [p.name for p in served(large)] == [
        "physics", f"lidar@{first}", f"control@{first}"]
