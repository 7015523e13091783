"""A full disk stops the run at a tick with exit code 5, naming the file and its file
system; the manifest says where it stopped, and the bag keeps (or, once there is room, the
finish command writes) every tick before it (issue 40, item 3). The disk is a 4 MiB tmpfs
where this machine lets the test mount one, and a file-size limit (RLIMIT_FSIZE) always."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tests.helpers import ORCHESTRATE, ROOT, nav_without_camera_doc
from tests.test_supervision import bag_counts

LIMIT = 1024 * 1024  # the file-size limit: physics's part reaches it after some ticks
FINISH = [sys.executable, "-m", "orchestrator.outputs.finish"]


def _tmpfs(where: Path, size: str) -> bool:
    where.mkdir(parents=True, exist_ok=True)
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                          capture_output=True).returncode == 0


def _limit_file_size() -> None:  # in the orchestrator's process, before exec; nodes inherit it
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


@pytest.fixture(params=["tmpfs", "file size limit"])
def full_disk(request, tmp_path):
    """(where --out goes, what to give Popen, how to make room afterwards)."""
    if request.param == "tmpfs":
        out = tmp_path / "small"
        assert _tmpfs(out, "4m"), "the full-disk test needs to mount a 4 MiB tmpfs (root)"
        yield out, {}, lambda: subprocess.run(
            ["mount", "-o", "remount,size=64m", str(out)], check=True)
        subprocess.run(["umount", "-l", str(out)], check=False)
    else:
        yield tmp_path / "out", {"preexec_fn": _limit_file_size}, lambda: None


def test_a_full_disk_stops_the_run_at_a_tick_and_keeps_every_tick_before(tmp_path, full_disk):
    out, popen, make_room = full_disk
    scenario = tmp_path / "nav.yaml"
    doc = nav_without_camera_doc("120s")
    doc["success"]["stop_on_goal"] = False  # the disk fills before the end
    scenario.write_text(yaml.safe_dump(doc))
    proc = subprocess.run([*ORCHESTRATE, str(scenario), "--out", str(out), "--quiet"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300, **popen)
    assert proc.returncode == 5, proc.stderr[-3000:]
    (run_dir,) = list(out.iterdir())
    assert f"could not write {run_dir}/parts/" in proc.stderr
    assert "file system at" in proc.stderr and "Traceback" not in proc.stderr
    manifest = json.loads((run_dir / "manifest.json").read_text())  # whole, never empty
    assert manifest["outcome"]["status"] == "write_failed"
    failure = manifest["write_failure"]
    assert failure["tick"] > 100 and 0 < failure["complete_ticks"] <= failure["tick"]
    if manifest["outputs"]["bag"] is None:  # no room for the bag: the way to finish is named
        assert "python -m orchestrator.outputs.finish" in proc.stderr
        assert manifest["unfinished"] and (run_dir / "parts").is_dir()
        make_room()
        finish = subprocess.run([*FINISH, str(run_dir)], cwd=ROOT, capture_output=True,
                                text=True, timeout=300)
        assert finish.returncode == 0, finish.stderr
        assert not (run_dir / "parts").exists()
    counts = bag_counts(run_dir)  # every message read back and deserialised
    assert counts["/clock"] == counts["/odom"] == failure["complete_ticks"]
    assert json.loads((run_dir / "manifest.json").read_text())["outputs"]["bag"] == "bag"


def test_a_full_disk_in_process_stops_at_a_tick_and_keeps_every_tick_before(tmp_path):
    doc = nav_without_camera_doc("120s")
    doc["success"]["stop_on_goal"] = False
    scenario = tmp_path / "nav.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    out = tmp_path / "out"
    proc = subprocess.run([*ORCHESTRATE, str(scenario), "--out", str(out), "--quiet",
                           "--in-process"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300, preexec_fn=_limit_file_size)
    assert proc.returncode == 5, proc.stderr[-3000:]
    (run_dir,) = list(out.iterdir())
    assert "the run stopped at tick" in proc.stderr and "the orchestrator could not write" \
        in proc.stderr and "file system at" in proc.stderr
    failure = json.loads((run_dir / "manifest.json").read_text())["write_failure"]
    if not (run_dir / "bag").is_dir():
        finish = subprocess.run([*FINISH, str(run_dir)], cwd=ROOT, capture_output=True,
                                text=True, timeout=300)
        assert finish.returncode == 0, finish.stderr
    counts = bag_counts(run_dir)
    assert counts["/clock"] == counts["/odom"] == failure["complete_ticks"] == failure["tick"]
