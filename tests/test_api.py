"""The Python API (orchestrator.api), the run diff, and cosim-orchestrate --expect-digest."""

from __future__ import annotations

import pytest
from std_msgs.msg import Float64, Int64

from orchestrator.api import EXIT_CODES, FinishedRun, load, overrides_for, run
from orchestrator.cosim_orchestrate import main
from orchestrator.outputs.diff import (
    _expand,
    _runs,
    fingerprint,
    fingerprint_entries,
    first_difference,
    run_dir_entries,
)
from plan.errors import ScenarioError, SimulationError
from tests.helpers import ROOT, SCENARIOS, orchestrate

PROTOCOL = SCENARIOS / "protocol.yaml"


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> FinishedRun:
    """One in-process run of the protocol scenario with seed 3."""
    return run(PROTOCOL, in_process=True, seed=3, out=tmp_path_factory.mktemp("ref"), picture=False)


def test_overrides_for_turns_keywords_into_dotted_keys():
    """seed, duration, goal and node params become dotted keys; raw overrides win."""
    got = overrides_for(seed=4, duration="2s", goal={"x": 1.0},
                        params={"control": {"max_speed": 0.4}},
                        overrides={"seed": 5, "nodes.lidar.rate": 20})
    assert got == {"seed": 5, "duration": "2s", "goal.x": 1.0,
                   "nodes.control.params.max_speed": 0.4, "nodes.lidar.rate": 20}


def test_load_applies_overrides_without_touching_the_file():
    """Overrides reach the checked scenario; re-loading a Scenario keeps its overrides."""
    before = PROTOCOL.read_bytes()
    scenario = load(PROTOCOL, seed=11, duration="0.5s", params={"loop": {"gain": -0.2}})
    assert scenario.model.seed == 11 and scenario.schedule.n_ticks == 51
    assert scenario.nodes["loop"].params.gain == -0.2
    again = load(scenario, seed=12)
    assert again.model.seed == 12 and again.nodes["loop"].params.gain == -0.2
    assert PROTOCOL.read_bytes() == before


def test_run_result_has_status_digest_metrics_and_typed_messages(reference):
    """A FinishedRun: status, exit code, success, digest (= manifest's), metrics, rclpy messages."""
    assert (reference.status, reference.exit_code, reference.success) == ("success", 0, True)
    assert reference.digest == reference.manifest["digest"] and len(reference.digest) == 64
    assert reference.metrics_by_node["sink"]["activations"] == 101
    assert reference.metrics["activations"] == 101 and reference.ticks == 101
    loop = list(reference.messages("/loop"))
    assert len(loop) == 51 and all(isinstance(m, Float64) for _, m in loop)
    assert [stamp for stamp, _ in loop[:3]] == [0, 20_000_000, 40_000_000]
    assert isinstance(reference.last("/sink"), Int64)
    assert "/clock" in reference.topics() and reference.run_dir.is_dir()
    with pytest.raises(KeyError, match="/nope was not recorded"):
        list(reference.messages("/nope"))


def test_multi_process_run_gives_the_in_process_digest(reference, tmp_path):
    """Every node its own process, lockstep over ROS 2: the same digest as in-process."""
    result = run(PROTOCOL, seed=3, out=tmp_path, picture=False)
    assert result.status == "success" and result.digest == reference.digest
    assert result.manifest["transport"] == "ros2"


def test_errors_are_the_cli_exceptions(tmp_path):
    """Bad input is ScenarioError (nothing written); a failing node is SimulationError."""
    with pytest.raises(ScenarioError, match="nodes.nope"):
        run(PROTOCOL, in_process=True, out=tmp_path, overrides={"nodes.nope.rate": 10},
            picture=False)
    with pytest.raises(ScenarioError, match="foreign programs"):
        run(ROOT / "scenarios" / "nav_foreign.yaml", in_process=True, out=tmp_path, picture=False)
    assert not list(tmp_path.iterdir())
    faulty = {"nodes.sink.kind": "faulty", "nodes.sink.params.fail_at": 5}
    with pytest.raises(SimulationError, match="sink"):
        run(PROTOCOL, in_process=True, out=tmp_path, overrides=faulty, picture=False)
    failed = run(PROTOCOL, in_process=True, out=tmp_path, check=False, overrides=faulty,
                 picture=False)
    assert failed.status == "failed" and failed.exit_code == EXIT_CODES["failed"] == 3
    assert failed.digest is None and "sink" in failed.error


def test_tick_runs_round_trip():
    """Fingerprint ticks are arithmetic runs 'start:step:count'."""
    for ticks in ([0, 2, 4, 6, 7], [5], [], [1, 1, 2], [0, 1, 2, 3, 10, 20, 30]):
        assert _expand(_runs(ticks)) == ticks
    assert _runs([0, 2, 4, 6, 7]) == "0:2:4 7:1:1"


def test_first_difference_names_topic_and_tick(reference, tmp_path):
    """Against itself nothing differs; a changed parameter is found at its topic and tick,
    from the full bag and from the compact fingerprint alike."""
    entries, tick_ns = run_dir_entries(reference.run_dir)
    assert first_difference(entries, entries) is None
    assert first_difference(fingerprint_entries(fingerprint(entries)), entries) is None
    changed = run(PROTOCOL, in_process=True, seed=3, out=tmp_path,
                  params={"sink": {"noise": 5}}, picture=False)
    other, _ = run_dir_entries(changed.run_dir)
    diff = first_difference(entries, other, tick_ns)
    assert (diff.topic, diff.kind) == ("/sink", "differs")
    assert diff == first_difference(fingerprint_entries(fingerprint(entries)), other, tick_ns)
    assert f"topic /sink at tick {diff.tick}" in diff.describe()
    shorter = run(PROTOCOL, in_process=True, seed=3, out=tmp_path, duration="0.5s", picture=False)
    cut, _ = run_dir_entries(shorter.run_dir)
    assert first_difference(entries, cut).describe() == (
        "topic /middle at tick 51: the reference run has a message here, this run has none")


def test_cli_expect_digest(reference, tmp_path, capsys):
    """--expect-digest: 0 on a match; 4 on a mismatch, naming (with --against) the first
    topic and tick that differ; 2 for a malformed digest or a DIR that is not a run."""
    ok = orchestrate(PROTOCOL, tmp_path, "--in-process", "--seed", "3", "--quiet",
                     "--expect-digest", reference.digest.upper())
    assert ok.code == 0, ok.stderr
    against = orchestrate(PROTOCOL, tmp_path, "--in-process", "--seed", "3", "--quiet",
                          "--set", "nodes.sink.params.noise=5", "--against",
                          str(reference.run_dir))
    assert against.code == 4, against.stderr
    assert f"expected {reference.digest}" in against.stderr
    assert "First difference from" in against.stderr and "topic /sink at tick" in against.stderr
    before = set(tmp_path.iterdir())
    assert main([str(PROTOCOL), "--out", str(tmp_path), "--expect-digest", "abc"]) == 2
    assert "64 hex digits" in capsys.readouterr().err
    assert main([str(PROTOCOL), "--out", str(tmp_path), "--against", str(tmp_path / "no")]) == 2
    assert "not a run directory" in capsys.readouterr().err
    assert set(tmp_path.iterdir()) == before


NAV = ROOT / "scenarios" / "nav.yaml"
NAV_SHORT = ("--in-process", "--quiet", "--duration", "1s")  # 3 camera frames; no goal: exit 1
DEPTH_ONLY = ("--set", "nodes.camera.params.camera.max_depth=1.0")  # changes the depth image
LEFT_OUT = ("without the rendered topics (/camera/color/image_raw, /camera/depth/image_rect: "
            "left out of the comparison)")


@pytest.fixture(scope="module")
def nav_reference(tmp_path_factory):
    """One short in-process nav run with its camera, through the CLI."""
    ref = orchestrate(NAV, tmp_path_factory.mktemp("nav_ref"), *NAV_SHORT)
    assert ref.code == 1, ref.stderr
    return ref


def test_cli_ignore_rendered_leaves_the_camera_images_out_and_says_so(nav_reference, tmp_path):
    """A change that reaches only the rendered topics (the depth image's range) fails
    --against, naming them as the only difference, the renderer and --ignore-rendered. With
    --ignore-rendered a change elsewhere still fails, and the message names what was left
    out."""
    ref = nav_reference
    strict = orchestrate(NAV, tmp_path, *NAV_SHORT, *DEPTH_ONLY, "--against", str(ref.run_dir))
    assert strict.code == 4, strict.stderr
    assert "topic /camera/depth/image_rect at tick 0" in strict.stderr
    assert ("Only the rendered topics (/camera/color/image_raw, /camera/depth/image_rect) "
            "differ") in strict.stderr and "--ignore-rendered" in strict.stderr
    assert "egl: " in strict.stderr  # the renderer is named
    other = orchestrate(NAV, tmp_path, *NAV_SHORT, "--set",
                        "nodes.lidar.params.lidar.noise_stddev=0.02", "--expect-digest",
                        ref.manifest["digest_without_rendered"], "--ignore-rendered")
    assert other.code == 4, other.stderr
    assert f"the digest {LEFT_OUT} mismatch" in other.stderr


def test_cli_rendered_psnr_floor_compares_the_images_frame_by_frame(nav_reference, tmp_path):
    """--rendered-psnr DB: the rest must be equal (as with --ignore-rendered, which it
    implies); the images of the same run pass, identical; a depth image of another range
    falls below the floor while the colour image passes."""
    ref = nav_reference
    same = orchestrate(NAV, tmp_path, *NAV_SHORT, "--against", str(ref.run_dir),
                       "--rendered-psnr", "40")
    assert same.code == 1, same.stderr
    assert "at or above the PSNR floor of 40 dB" in same.stderr
    assert "/camera/color/image_raw: 3 frames, all identical" in same.stderr
    assert "/camera/depth/image_rect: 3 frames, all identical" in same.stderr
    depth = orchestrate(NAV, tmp_path, *NAV_SHORT, *DEPTH_ONLY, "--against", str(ref.run_dir),
                        "--rendered-psnr", "40")
    assert depth.code == 4, depth.stderr
    assert f"digest {LEFT_OUT}: {ref.manifest['digest_without_rendered']}" in depth.stderr
    assert "mismatch" not in depth.stderr  # everything but the images is equal
    assert "below the PSNR floor of 40 dB" in depth.stderr
    assert "/camera/color/image_raw: 3 frames, all identical" in depth.stderr
    assert "/camera/depth/image_rect: lowest " in depth.stderr
    assert main([str(NAV), "--out", str(tmp_path), "--rendered-psnr", "40"]) == 2


def test_run_without_its_picture(tmp_path):
    """``run(picture=False)``: no report.png (RunOptions.picture), the same digest."""
    bare = run(SCENARIOS / "protocol.yaml", in_process=True, out=tmp_path / "bare",
               picture=False)
    drawn = run(SCENARIOS / "protocol.yaml", in_process=True, out=tmp_path / "drawn")
    assert not (bare.run_dir / "report.png").exists()
    assert (drawn.run_dir / "report.png").exists() and bare.digest == drawn.digest
