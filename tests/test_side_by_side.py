"""Runs side by side on one machine: each takes a ROS domain of its own; a pinned domain that
another run has is refused at start, naming that run (issue 40, item 1)."""

from __future__ import annotations

import os
import re
import subprocess
import time

import pytest
import yaml

from orchestrator.domains import DomainLease
from tests.helpers import ORCHESTRATE, ROOT, nav_without_camera_doc, orchestrate

DIGEST = re.compile(r"digest ([0-9a-f]{64})")
DOMAIN_LINE = re.compile(r"ROS domain (\d+) \(this run's own")


def _nav(tmp_path, duration: str = "1s"):
    path = tmp_path / "nav.yaml"
    path.write_text(yaml.safe_dump(nav_without_camera_doc(duration)))
    return path


def _unpinned_env() -> dict[str, str]:
    """The environment of a user who set no ROS_DOMAIN_ID (nor a discovery range)."""
    env = dict(os.environ)
    for name in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY"):
        env.pop(name, None)
    return env


@pytest.mark.parametrize("count", [2, 4])
def test_runs_started_together_each_take_a_domain_and_give_the_reference_digest(
        tmp_path, count):
    scenario = _nav(tmp_path)
    reference = orchestrate(scenario, tmp_path / "ref", "--in-process")
    want = DIGEST.search(reference.stdout).group(1)
    procs = [subprocess.Popen([*ORCHESTRATE, str(scenario), "--out", str(tmp_path / f"r{i}")],
                              cwd=ROOT, env=_unpinned_env(), text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for i in range(count)]
    results = [p.communicate(timeout=300) for p in procs]
    domains = set()
    for proc, (out, err) in zip(procs, results, strict=True):
        assert proc.returncode == reference.code, err[-3000:]
        assert DIGEST.search(out).group(1) == want, err[-3000:]
        line = DOMAIN_LINE.search(err)
        assert line and f"ROS_DOMAIN_ID={line.group(1)} ros2 topic list" in err, err[-2000:]
        assert "discovery on this machine only" in err
        domains.add(line.group(1))
    assert len(domains) == count


def test_a_pinned_domain_with_a_run_going_is_refused_naming_that_run(tmp_path):
    scenario = _nav(tmp_path, "30s")
    with DomainLease(wait_s=30) as domain:
        env = {**_unpinned_env(), "ROS_DOMAIN_ID": str(domain)}
        first = subprocess.Popen([*ORCHESTRATE, str(scenario), "--out", str(tmp_path / "a")],
                                 cwd=ROOT, env=env, text=True, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE)
        try:
            deadline = time.monotonic() + 120
            while not list((tmp_path / "a").glob("*/logs")) and time.monotonic() < deadline:
                assert first.poll() is None
                time.sleep(0.1)
            for how in (("--domain", str(domain)), ()):
                second = orchestrate(scenario, tmp_path / "b", *how, env=env)
                assert second.code == 2, second.stderr
                assert f"ROS domain {domain} is in use by another cosim run" in second.stderr
                assert f"cosim-orchestrate {scenario}" in second.stderr  # the first, by name
                assert f"outputs in {tmp_path / 'a'}" in second.stderr
                assert not (tmp_path / "b").exists()  # nothing started or written
        finally:
            first.terminate()
            first.communicate(timeout=120)


def test_a_domain_out_of_range_is_bad_input(tmp_path):
    run = orchestrate(_nav(tmp_path), tmp_path / "out", "--domain", "300")
    assert run.code == 2
    assert "--domain='300': expected a ROS domain id" in run.stderr
    assert not (tmp_path / "out").exists()
