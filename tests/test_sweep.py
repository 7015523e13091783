"""cosim-sweep: the plan, the embedded pool, a local Ray cluster, failures, Ctrl-C, resume.

Every sweep runs as a real process (``python -m orchestrator.sweep``). "Alone" digests come
from independent runs of the same seeds through the API in this process. The Ray cluster
is a real one started here (head and one worker on 127.0.0.1, one CPU each) and stopped
by its processes' session ids; no test leaves a sweep worker or a Ray process behind.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil
import pytest

from orchestrator.sweep.cli import main
from orchestrator.sweep.combinations import parse_seeds, parse_sweep_sets, plan_runs, run_id
from orchestrator.sweep.one_run import flat_metrics
from orchestrator.sweep.results import _column, to_skip
from tests.helpers import ROOT, SCENARIOS

SWEEP = [sys.executable, "-m", "orchestrator.sweep"]
SCENARIO = SCENARIOS / "protocol.yaml"
SHORT = ["--set", "duration=100ms"]
SEEDS = range(1, 5)
FAULTY = {"nodes.source.kind": "faulty", "nodes.source.params.mode": "exit"}
"""The source node can be made to fail: with fail_at=3, the run's process exits at tick 3."""


def faulty(fail_at: str) -> list[str]:
    """The --set arguments of FAULTY, the source failing at the tick(s) ``fail_at``."""
    values = {**FAULTY, "nodes.source.params.fail_at": fail_at}
    return [arg for key, value in values.items() for arg in ("--set", f"{key}={value}")]


EIGHT_RUNS = ["--seeds", "1-4", *faulty("-1,3")]
"""Four seeds, each with a run that finishes and one whose process dies (exit code 7)."""


def sweep(out: Path, *args: str, timeout: float = 240, picture: bool = False
          ) -> subprocess.CompletedProcess:
    """Run cosim-sweep on the protocol scenario (100 ms) as a real process; its runs draw
    no report.png unless ``picture``."""
    drawn = () if picture else ("--no-picture",)
    proc = subprocess.run([*SWEEP, str(SCENARIO), "--out", str(out), *SHORT, *args, *drawn],
                          cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    assert not leftovers(out), f"processes left behind: {leftovers(out)}"
    return proc


def leftovers(out: Path) -> list[str]:
    """Processes still running that belong to the sweep writing into ``out``."""
    found = []
    for proc in psutil.process_iter(["cmdline"]):
        cmdline = " ".join(proc.info["cmdline"] or [])
        try:
            if str(out) in cmdline and proc.status() != psutil.STATUS_ZOMBIE:
                found.append(f"{proc.pid} {cmdline[:120]}")
        except psutil.Error:
            continue
    return found


def table(out: Path) -> list[dict]:
    """The Parquet table's rows, checked against the CSV (same runs, digests, statuses)."""
    import pyarrow.parquet as pq

    rows = pq.read_table(out / "results.parquet").to_pylist()
    with open(out / "results.csv", newline="") as f:
        from_csv = list(csv.DictReader(f))
    assert [(r["run_id"], r["status"], r["digest"] or "") for r in rows] == \
        [(r["run_id"], r["status"], r["digest"]) for r in from_csv]
    return rows


def records(out: Path) -> dict[str, float]:
    """Each run's result.json and when it was written."""
    return {p.parent.name: p.stat().st_mtime_ns for p in out.glob("runs/*/result.json")}


@pytest.fixture(scope="module")
def alone(tmp_path_factory) -> dict[int, str]:
    """The digest of each seed's finishing run alone (an ordinary in-process run of the same
    scenario, seed and values, in this process)."""
    from orchestrator.api import run

    out = tmp_path_factory.mktemp("alone")
    overrides = {**FAULTY, "nodes.source.params.fail_at": -1}
    return {seed: run(SCENARIO, in_process=True, out=out, seed=seed, duration="100ms",
                      overrides=overrides, picture=False).digest for seed in SEEDS}


def check_eight_runs(out: Path, proc: subprocess.CompletedProcess, alone: dict[int, str],
                     crash_error: str) -> list[dict]:
    """The 8-run sweep: every finishing run has its digest alone, every crash is reported
    with its error, the table is complete; its rows."""
    assert proc.returncode == 3, proc.stderr  # some runs failed
    rows = table(out)
    assert [(r["seed"], r["nodes.source.params.fail_at"]) for r in rows] == \
        [(seed, fail_at) for seed in SEEDS for fail_at in (-1, 3)]
    finished = {r["seed"]: r["digest"] for r in rows if r["nodes.source.params.fail_at"] == -1}
    assert finished == alone
    for row in rows:
        if row["nodes.source.params.fail_at"] == -1:
            assert row["status"] == "success" and row["success"] and row["wall_s"] > 0, row
            assert row["sink.activations"] == 11  # metrics are columns, by node when shared
        else:
            assert row["status"] == "crashed" and crash_error in row["error"], row
            assert not row["success"] and row["digest"] is None
    assert "8 of 8 runs finished: 4 succeeded, 0 missed the goal, 4 failed (4 crashed)" \
        in proc.stdout
    return rows


# -- the plan -------------------------------------------------------------------------------

def test_seeds_ranges_and_lists():
    assert parse_seeds("1-3,10,2") == [1, 2, 3, 10]
    assert parse_seeds("7") == [7]
    for bad in ("5-1", "a", "1-", ""):
        with pytest.raises(ValueError, match="--seeds"):
            parse_seeds(bad)


def test_set_values_are_yaml_lists():
    values = parse_sweep_sets(["nodes.c.params.max_speed=0.3,0.5", "goal.x=[1,2],[3,4]",
                               "duration=10s"])
    assert values == {"nodes.c.params.max_speed": [0.3, 0.5], "goal.x": [[1, 2], [3, 4]],
                      "duration": ["10s"]}
    for bad, why in (("seed=1,2", "--seeds"), ("x", "KEY=V1"), ("x=[1", "YAML")):
        with pytest.raises(ValueError, match=why):
            parse_sweep_sets([bad])


def test_plan_is_the_product_with_stable_ids(tmp_path):
    specs = plan_runs(SCENARIO, [1, 2], {"a.b": [0.5, "0.5"], "c": [1, 2, 3]}, tmp_path,
                      in_process=True, processes=1)
    assert len(specs) == 12 and len({s.run_id for s in specs}) == 12
    assert [s.seed for s in specs] == [1] * 6 + [2] * 6
    assert specs[0].overrides() == {"seed": 1, "a.b": 0.5, "c": 1}
    assert run_id(1, {"a.b": 0.5}) == run_id(1, {"a.b": 0.5}) != run_id(1, {"a.b": "0.5"})
    assert all(s.out.parent == (tmp_path / "runs").resolve() for s in specs)


def test_resume_skips_finished_runs_and_retries_failed_ones_on_request(tmp_path):
    specs = plan_runs(SCENARIO, [1, 2, 3], {}, tmp_path, in_process=True, processes=1)
    found = {specs[0].run_id: {"status": "success"}, specs[1].run_id: {"status": "crashed"}}
    assert to_skip(specs, found, retry_failed=False) == {specs[0].run_id, specs[1].run_id}
    assert to_skip(specs, found, retry_failed=True) == {specs[0].run_id}


def test_metrics_named_by_several_nodes_are_named_by_node():
    by_node = {"physics": {"collisions": 0, "x": 1.5}, "a": {"activations": 3},
               "b": {"activations": 5, "label": "text"}}
    assert flat_metrics(by_node) == {"collisions": 0.0, "x": 1.5, "a.activations": 3.0,
                                     "b.activations": 5.0}


def test_table_columns_keep_numbers_and_write_other_values_as_json():
    assert _column([1, 2, None]).type == "int64"
    assert _column([0.5, 1]).type == "double"
    assert _column([[1, 2], "x"]).to_pylist() == ["[1, 2]", '"x"']
    assert _column([None, None]).type == "string"


@pytest.mark.parametrize("args, expected", [
    (["--seeds", "5-1"], "--seeds"),
    (["--seeds", "1-2", "--set", "nodes.nope.rate=10,20"], "nope"),
    (["--seeds", "1-2", "--set", "nodes.source.rate=100,0"], "rate"),
    (["--seeds", "1", "--retry-failed"], "--resume"),
    (["--seeds", "1", "--ray", "nowhere"], "host:port"),
])
def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, args, expected):
    out = tmp_path / "sweep"
    assert main([str(SCENARIO), "--out", str(out), *args]) == 2
    assert expected in capsys.readouterr().err
    assert not out.exists()


def test_a_directory_holding_a_sweep_needs_resume(tmp_path, capsys):
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "sweep.json").write_text(json.dumps({"scenario": str(SCENARIO)}))
    assert main([str(SCENARIO), "--out", str(out), "--seeds", "1"]) == 2
    assert "--resume" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["sweep.json"]


# -- the embedded pool ----------------------------------------------------------------------

def test_embedded_pool_runs_have_their_digests_alone_crashes_are_reported_and_resume(
        tmp_path, alone):
    out = tmp_path / "sweep"
    proc = sweep(out, *EIGHT_RUNS)
    rows = check_eight_runs(out, proc, alone, "the run's process died (exit code 7)")
    for row in rows:  # each row points at its run, whose manifest has the same digest
        if row["digest"]:
            manifest = json.loads((out / row["run_dir"] / "manifest.json").read_text())
            assert manifest["digest"] == row["digest"]
            assert manifest["outputs"]["report"] is None  # --no-picture
    assert (out / "summary.png").read_bytes()[:4] == b"\x89PNG"

    before = records(out)
    again = sweep(out, *EIGHT_RUNS, "--resume")
    assert again.returncode == 3, again.stderr
    assert "0 run(s) finished" in again.stdout and "8 skipped" in again.stdout
    assert records(out) == before  # nothing ran again
    assert table(out) == rows


def test_a_hung_run_is_stopped_at_the_timeout_and_recorded(tmp_path):
    out = tmp_path / "sweep"
    proc = sweep(out, "--seeds", "1", "--set", "nodes.source.kind=faulty",
                 "--set", "nodes.source.params.mode=hang",
                 "--set", "nodes.source.params.fail_at=-1,3", "--timeout", "3")
    assert proc.returncode == 3, proc.stderr
    finished, hung = table(out)
    assert finished["status"] == "success"
    assert hung["status"] == "timeout" and "after 3 s (--timeout)" in hung["error"]


def test_multi_process_runs_each_lease_a_ros_domain(tmp_path, alone):
    out = tmp_path / "sweep"
    proc = sweep(out, "--seeds", "1-2", *faulty("-1"), "--multi-process", "--jobs", "2",
                 picture=True)
    assert proc.returncode == 0, proc.stderr
    rows = table(out)
    assert {r["seed"]: r["digest"] for r in rows} == {1: alone[1], 2: alone[2]}
    assert all((out / r["run_dir"] / "report.png").is_file() for r in rows)
    domains = [r["ros_domain"] for r in rows]
    assert len(set(domains)) == 2 and str(domains[0]) != os.environ["ROS_DOMAIN_ID"]


def test_ctrl_c_stops_every_run_writes_the_table_and_resume_finishes(tmp_path):
    out = tmp_path / "sweep"
    args = [str(SCENARIO), "--out", str(out), "--seeds", "1-8", "--set", "duration=3s"]
    proc = subprocess.Popen([*SWEEP, *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not records(out) and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        started = psutil.Process(proc.pid).children(recursive=True)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr
    assert not [p for p in started if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    assert not leftovers(out)
    finished = records(out)
    assert 1 <= len(finished) < 8
    assert sorted(r["run_id"] for r in table(out)) == sorted(finished)

    resumed = subprocess.run([*SWEEP, *args, "--resume"], cwd=ROOT, capture_output=True,
                             text=True, timeout=240)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{8 - len(finished)} run(s) finished" in resumed.stdout
    assert {k: v for k, v in records(out).items() if k in finished} == finished
    rows = table(out)
    assert len(rows) == 8 and all(r["status"] == "success" for r in rows)


# -- a local Ray cluster --------------------------------------------------------------------

def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _sessions_processes(sessions: set[int]) -> list[psutil.Process]:
    found = []
    for proc in psutil.process_iter():
        try:
            if os.getsid(proc.pid) in sessions and proc.status() != psutil.STATUS_ZOMBIE:
                found.append(proc)
        except (OSError, psutil.Error):
            continue
    return found


@pytest.fixture(scope="module")
def ray_cluster():
    """A Ray head and one worker node on 127.0.0.1, one CPU each; its address. Every
    process of the cluster is in the session of the `ray start` that made it, so teardown
    stops exactly those (never `ray stop`, which stops every Ray of the machine)."""
    ray = str(Path(sys.executable).with_name("ray"))
    port = _free_port()
    temp = tempfile.mkdtemp(prefix="cosim-ray-", dir="/tmp")  # socket paths must be short
    common = ["--num-cpus=1", "--disable-usage-stats",
              f"--dashboard-agent-listen-port={_free_port()}"]
    commands = [[ray, "start", "--head", f"--port={port}", "--node-ip-address=127.0.0.1",
                 "--include-dashboard=false", f"--temp-dir={temp}",
                 f"--ray-client-server-port={_free_port()}", *common],
                [ray, "start", f"--address=127.0.0.1:{port}", "--node-ip-address=127.0.0.1",
                 *common]]
    # Ray's own setting, explicit: since 2.5x a ray.init() cluster leaves ~/.ray/auth_token
    # behind, which turns token auth on for a later `ray start --head` but not its workers.
    env = {**os.environ, "RAY_AUTH_MODE": "disabled"}
    sessions: set[int] = set()
    try:
        for command in commands:
            start = subprocess.Popen(command, start_new_session=True, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, env=env)
            sessions.add(start.pid)
            output, _ = start.communicate(timeout=180)
            assert start.returncode == 0, output
        yield f"127.0.0.1:{port}"
    finally:
        procs = _sessions_processes(sessions)
        for proc in procs:
            proc.terminate()
        _, alive = psutil.wait_procs(procs, timeout=3)
        for proc in alive:
            proc.kill()
        psutil.wait_procs(alive, timeout=10)
        assert not _sessions_processes(sessions), "Ray processes left behind"


def test_ray_cluster_runs_have_their_digests_alone_crashes_are_reported_and_resume(
        tmp_path, ray_cluster, alone):
    out = tmp_path / "sweep"
    proc = sweep(out, *EIGHT_RUNS, "--ray", ray_cluster)
    rows = check_eight_runs(out, proc, alone, "the Ray worker running the run died")

    before = records(out)
    retried = sweep(out, *EIGHT_RUNS, "--ray", ray_cluster, "--resume", "--retry-failed")
    assert retried.returncode == 3, retried.stderr
    assert "4 run(s) finished" in retried.stdout and "4 skipped" in retried.stdout
    after = records(out)
    for row in rows:  # the finished runs were kept, the crashed ones ran (and crashed) again
        assert (after[row["run_id"]] == before[row["run_id"]]) == (row["status"] == "success")
    assert [r["status"] for r in table(out)] == [r["status"] for r in rows]
