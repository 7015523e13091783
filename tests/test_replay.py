"""--replay refuses what it cannot replay faithfully: exit 2, nothing started or written.
(Replays themselves are tested where the runs they replay are made: test_external,
test_rosbridge, test_ros_clients_nav, test_twin.)"""

from __future__ import annotations

import subprocess

import pytest

from tests.helpers import ORCHESTRATE, ROOT


def replay(tmp_path, run_dir, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*ORCHESTRATE, "--replay", str(run_dir), "--out",
                           str(tmp_path / "out"), *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)


@pytest.mark.parametrize("args, says", [
    ([], "has no manifest.json"),
    (["--seed", "3"], "has no manifest.json"),  # the directory is checked first
    (["--twin", "ws://127.0.0.1:9"], "takes no --twin"),
])
def test_what_cannot_be_replayed_is_exit_2(tmp_path, args, says):
    done = replay(tmp_path, tmp_path, *args)
    assert done.returncode == 2 and says in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()


def test_a_replay_takes_no_overrides(tmp_path):
    (tmp_path / "manifest.json").write_text('{"scenario": {"file": "x"}}')
    done = replay(tmp_path, tmp_path, "--seed", "3")
    assert done.returncode == 2 and "takes no overrides" in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()


def test_a_scenario_file_and_replay_together_are_exit_2(tmp_path):
    done = subprocess.run([*ORCHESTRATE, str(ROOT / "scenarios" / "nav.yaml"), "--replay",
                           str(tmp_path)], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2 and "one of them" in done.stderr, done.stderr


def test_a_scenario_changed_since_the_run_is_exit_2(tmp_path):
    nav = ROOT / "scenarios" / "nav.yaml"
    (tmp_path / "bag").mkdir()
    (tmp_path / "manifest.json").write_text(
        f'{{"scenario": {{"file": "{nav}", "sha256": "{"0" * 64}", "overrides": {{}}}}, '
        '"ticks": 10, "tick_ns": 20000000, "digest": null}')
    done = replay(tmp_path, tmp_path)
    assert done.returncode == 2 and "changed since the run was recorded" in done.stderr
    assert not (tmp_path / "out").exists()
