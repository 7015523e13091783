"""The pytest plugin (orchestrator.pytest_plugin), tested with pytest's own pytester.

The inner sessions run as subprocesses: an in-process pytester session drops the modules it
imported afterwards, and C extensions (numpy, MuJoCo, rclpy) cannot be imported twice.
"""

from __future__ import annotations

import json
import subprocess
import sys

import psutil

from orchestrator.pytest_plugin import TOKEN_ENV
from tests.helpers import ROOT, SCENARIOS

pytest_plugins = ["pytester"]

PROTOCOL = SCENARIOS / "protocol.yaml"


def test_plugin_is_registered_by_the_entry_point(pytester):
    """Installing cosim is enough: the options and the marker are there."""
    result = pytester.runpytest_inprocess("--help")
    result.stdout.fnmatch_lines(["*--cosim-update-golden*"])
    assert pytester.runpytest_inprocess("--markers").stdout.str().count("cosim_seeds") == 1


def test_seeds_domains_and_a_missed_goal(pytester, tmp_path):
    """@cosim_seeds runs a test per seed, each run with that seed and a ROS domain of its
    own; a run that misses its goal fails the user's assert, and the report shows the run."""
    log = tmp_path / "domains.txt"
    pytester.makepyfile(f"""
        import os
        import pytest

        @pytest.mark.cosim_seeds(1, 2, 3)
        def test_protocol(cosim):
            run = cosim.run({str(PROTOCOL)!r}, in_process=True)
            assert run.success and run.exit_code == 0
            assert run.scenario.model.seed == cosim.seed
            assert os.environ["ROS_DOMAIN_ID"] == str(cosim.domain_id)
            with open({str(log)!r}, "a") as f:
                f.write(f"{{cosim.seed}} {{cosim.domain_id}} {{run.digest}}\\n")

        def test_goal(cosim):
            run = cosim.run({str(PROTOCOL)!r}, in_process=True, goal={{"x": 1.0, "y": 1.0}})
            assert run.status == "goal_not_met" and run.exit_code == 1
            assert run.success, run.summary()
    """)
    result = pytester.runpytest_subprocess("-v")
    result.assert_outcomes(passed=3, failed=1)
    result.stdout.fnmatch_lines(["*test_protocol?seed=1? PASSED*", "*cosim runs*",
                                 "goal_not_met: digest *", "*no golden digest*"])
    rows = [line.split() for line in log.read_text().splitlines()]
    assert [r[0] for r in rows] == ["1", "2", "3"]
    assert len({r[1] for r in rows}) == 3 and len({r[2] for r in rows}) == 3


def test_changed_digest_names_first_topic_and_tick(pytester, monkeypatch):
    """--cosim-update-golden records; an unchanged run passes, a changed one fails naming
    the first topic and tick that differ."""
    pytester.makepyfile(f"""
        import os

        def test_same(cosim):
            cosim.run({str(PROTOCOL)!r}, in_process=True)

        def test_golden(cosim):
            noise = int(os.environ.get("SINK_NOISE", "0"))
            cosim.run({str(PROTOCOL)!r}, in_process=True, seed=2,
                      params={{"sink": {{"noise": noise}}}})
    """)
    pytester.runpytest_subprocess("--cosim-update-golden").assert_outcomes(passed=2)
    golden = json.loads((pytester.path / "test_changed_digest_names_first_topic_and_tick"
                         ".golden.json").read_text())
    entry = golden["runs"]["test_golden"]
    assert len(entry["digest"]) == 64 and entry["messages"]["/loop"]["ticks"] == "0:2:51"
    assert len(entry["digest_without_rendered"]) == 64 and entry["rendered_topics"] == []
    assert {"python", "numpy", "mujoco"} <= set(entry["versions"])
    assert "renderer" not in entry["versions"]  # no images covered
    # as if recorded with another MuJoCo: the failure says which versions differ
    golden_file = pytester.path / "test_changed_digest_names_first_topic_and_tick.golden.json"
    now_mujoco = entry["versions"]["mujoco"]
    entry["versions"]["mujoco"] = "0.0.0-golden"
    golden_file.write_text(json.dumps(golden))
    monkeypatch.setenv("SINK_NOISE", "3")
    result = pytester.runpytest_subprocess()
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines([
        "*the run digest of test_golden changed*",
        f"*golden: {entry['digest']}*",
        "*first difference: topic /sink at tick 1 (t = 0.010 s): the message differs*",
        f"*versions: The versions a digest depends on differ*mujoco 0.0.0-golden -> "
        f"{now_mujoco}*",
        "*--cosim-update-golden*"])
    result = pytester.runpytest_subprocess("--cosim-ignore-rendered")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines([
        "*the digest without the rendered topics (none in this run: left out of the "
        "comparison) of test_golden changed*",
        f"*golden: {entry['digest_without_rendered']}*",
        "*first difference: topic /sink at tick 1*"])


def test_no_process_left_after_a_failing_test(pytester, tmp_path):
    """A test whose multi-process run fails, and that started a process of its own, leaves
    nothing running: the run stops its nodes, the fixture stops the rest."""
    pid_file = tmp_path / "pid"
    pytester.makepyfile(f"""
        import subprocess

        def test_fails(cosim):
            stray = subprocess.Popen(["sleep", "60"])
            open({str(pid_file)!r}, "w").write(f"{{stray.pid}} {{cosim.token}}")
            cosim.run({str(PROTOCOL)!r}, overrides={{"nodes.sink.kind": "faulty",
                                                    "nodes.sink.params.fail_at": 10}})
    """)
    result = pytester.runpytest_subprocess()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*SimulationError*sink*"])
    pid, token = pid_file.read_text().split()
    assert not _alive(int(pid))
    assert not [p for p in psutil.process_iter() if _alive(p.pid) and _token(p) == token]


def test_no_forked_orphan_left_after_a_test(pytester, tmp_path):
    """A process forked (no exec, so without the test's token in its environment) whose parent
    ended is still stopped when the test ends."""
    pid_file = tmp_path / "pid"
    pytester.makepyfile(f"""
        import os
        import time

        def test_forks(cosim):
            r, w = os.pipe()
            child = os.fork()
            if child == 0:
                try:
                    grandchild = os.fork()
                    if grandchild == 0:
                        os.close(w)
                        time.sleep(120)
                    else:
                        os.write(w, str(grandchild).encode())
                finally:
                    os._exit(0)
            os.close(w)
            os.waitpid(child, 0)
            open({str(pid_file)!r}, "w").write(os.fdopen(r).read())
    """)
    result = pytester.runpytest_subprocess()
    result.assert_outcomes(passed=1)
    pids = [int(pid_file.read_text())]
    try:
        assert not [pid for pid in pids if _alive(pid)]
    finally:
        for pid in pids:
            if _alive(pid):
                psutil.Process(pid).kill()


def _alive(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def _token(proc: psutil.Process) -> str | None:
    try:
        return proc.environ().get(TOKEN_ENV)
    except psutil.Error:
        return None


def test_the_example_passes():
    """examples/test_my_controller.py: a user's own controller reaches the goal in 3 seeds."""
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "examples/test_my_controller.py"], cwd=ROOT, capture_output=True,
                          text=True, timeout=240)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "3 passed" in proc.stdout
