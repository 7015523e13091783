"""A run of more processes than ROS 2's LOCALHOST discovery reaches still starts: rmw_fastrtps
probes the ports of 32 participant ids on 127.0.0.1, so two participants both above id 31
never meet; cosim widens the range for such a run (orchestrator.run_domain.widen_discovery).
A chain of 33 node processes (ids 0-32, the orchestrator's two above them) is the smallest run
whose start needs that: without the widening, the last node and the orchestrator never meet."""

from __future__ import annotations

import yaml

from orchestrator import run_domain
from runtime.transport.ros2 import PROFILE
from tests.helpers import orchestrate

NODES = 33


def chain(tmp_path):
    """NODES counters, each fed by the one before it, each in a process of its own."""
    nodes = [{"name": "n0", "kind": "counter", "rate": 100, "params": {"output": "/n0"}}]
    nodes += [{"name": f"n{i}", "kind": "counter", "rate": 100, "params": {"output": f"/n{i}"},
               "inputs": [{"topic": f"/n{i - 1}", "mode": "same_tick"}]}
              for i in range(1, NODES)]
    doc = {"name": "chain", "seed": 1, "duration": "0.05s",
           "deadlines": {"start": "90s", "tick": "30s"}, "nodes": nodes}
    path = tmp_path / "chain.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_run_of_more_processes_than_localhost_discovery_reaches_starts(tmp_path):
    assert NODES + 2 > run_domain.LOCALHOST_PEERS + 1  # two participants above id 31
    # as a test process that has used the ros2 transport passes them on
    env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "FASTRTPS_DEFAULT_PROFILES_FILE": str(PROFILE)}
    run = orchestrate(chain(tmp_path), tmp_path / "runs", timeout=180, env=env)
    assert run.code == 0, run.stderr
    log = (run.run_dir / "logs" / "orchestrator.log").read_text()
    assert f"{NODES + 2} DDS participants: LOCALHOST discovery widened" in log
    assert run.manifest["ticks"] == 6
    # what the run prints for a tool to join it still says LOCALHOST (a tool's own range
    # reaches the run: the run's participants above id 31 announce themselves to it)
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=" in run.stdout + run.stderr
