"""Running the live endpoints' real clients from tests: the orchestrator and cosim-node as
processes, the JavaScript clients under node (tests/js, installed by `make install`)."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import time
from pathlib import Path

import yaml

from tests.helpers import COSIM_NODE, ORCHESTRATE, ROOT

JS = ROOT / "tests" / "js"
NAV = ROOT / "scenarios" / "nav.yaml"


def free_port() -> int:
    """A TCP port free on loopback now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def wait_listening(port: int, proc: subprocess.Popen, timeout: float = 60) -> None:
    """Wait until something accepts connections on ``port`` (fail if ``proc`` ends first)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise AssertionError(f"the process ended ({proc.returncode}) before listening: "
                                 f"{proc.stderr.read() if proc.stderr else ''}")
        with socket.socket() as probe:
            if probe.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise AssertionError(f"nothing listens on {port} after {timeout} s")


def nav_doc(duration: str = "3s") -> dict:
    """scenarios/nav.yaml as a dict, with an absolute world and a shorter duration."""
    doc = yaml.safe_load(NAV.read_text())
    doc["duration"] = duration
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    return doc


def drive_scenario(tmp_path: Path, duration: str = "4s") -> Path:
    """nav's physics and lidar with no controller: /cmd_vel comes from outside (a client)."""
    doc = nav_doc(duration)
    doc["name"] = "drive"
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] in ("physics", "lidar")]
    doc["external"] = {"rate": 10, "topics": {"/cmd_vel": "geometry_msgs/msg/Twist"}}
    doc.pop("goal", None)
    doc["success"] = {"reach_goal": False, "max_collisions": 10}
    path = tmp_path / "drive.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def write(tmp_path: Path, doc: dict, name: str) -> Path:
    """Write a scenario dict."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def orchestrate(scenario: Path, out: Path, *args: str) -> subprocess.Popen:
    """cosim-orchestrate as a running process."""
    return subprocess.Popen([*ORCHESTRATE, str(scenario), "--out", str(out), "--quiet",
                             "--no-picture", *args],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def cosim_node(*args: str) -> subprocess.Popen:
    """cosim-node as a running process."""
    return subprocess.Popen([*COSIM_NODE, *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def node_client(script: str, *args: str) -> subprocess.Popen:
    """One of the JavaScript clients (tests/js) under node; it prints one JSON line."""
    node = shutil.which("node")
    assert node, "node is needed for the JavaScript clients (see tests/js)"
    assert (JS / "node_modules").is_dir(), "run `make install` (npm ci in tests/js)"
    return subprocess.Popen([node, str(JS / script), *args], cwd=JS, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def finish(proc: subprocess.Popen, timeout: float = 120) -> tuple[int, str, str]:
    """Wait for a process; kill it (and fail) when it outlives ``timeout``."""
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise AssertionError(f"{proc.args[:3]} did not end in {timeout} s:\n"
                             f"{err[-3000:]}") from None
    return proc.returncode, out, err


def summary(proc: subprocess.Popen, timeout: float = 120) -> dict:
    """A JavaScript client's summary line."""
    code, out, err = finish(proc, timeout)
    assert code == 0 and out.strip(), f"client failed ({code}): {err[-3000:]}"
    return json.loads(out.strip().splitlines()[-1])


def run_dir(out: Path) -> Path:
    """The only run directory under ``out``."""
    (found,) = [p for p in out.iterdir() if p.is_dir()]
    return found


def manifest(out: Path) -> dict:
    """The manifest of the only run under ``out``."""
    return json.loads((run_dir(out) / "manifest.json").read_text())
