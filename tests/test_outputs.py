"""Run outputs: the bag read back by a library that did not write it, manifest, picture,
end-of-run summary and the progress display."""

from __future__ import annotations

import io
import re
import time
from collections import Counter, defaultdict
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from descriptions.load import load_scenario
from orchestrator.outputs.picture import write_report_png
from orchestrator.outputs.report import print_outcome
from orchestrator.progress import REDRAW_S, Progress
from runtime.timing import PARTS
from tests.helpers import ROOT, SCENARIOS, orchestrate

PROTOCOL = SCENARIOS / "protocol.yaml"
NAV = ROOT / "scenarios" / "nav.yaml"
NAV_DURATION = "5s"
FINAL_LINE = re.compile(r"^(success|goal_not_met|failed|interrupted): digest ([0-9a-f]{64}|-) "
                        r"\((\d+\.\d\d) s\) -> (.+)$")


class BagContents:
    """Every message of a run's bag, decoded by mcap_ros2: topic -> [(log time, message)]."""

    def __init__(self, run_dir: Path):
        files = sorted((run_dir / "bag").glob("*.mcap"))
        assert len(files) == 1, files
        self.messages: dict[str, list[tuple[int, object]]] = defaultdict(list)
        self.publish_times: dict[str, list[int]] = defaultdict(list)
        with files[0].open("rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            summary = reader.get_summary()
            self.channel_counts = Counter()
            for cid, channel in summary.channels.items():
                self.channel_counts[channel.topic] += summary.statistics.channel_message_counts.get(
                    cid, 0)
            self.schemas = {ch.topic: summary.schemas[ch.schema_id].name
                            for ch in summary.channels.values()}
            for _, channel, message, decoded in reader.iter_decoded_messages():
                self.messages[channel.topic].append((message.log_time, decoded))
                self.publish_times[channel.topic].append(message.publish_time)


@pytest.fixture(scope="module")
def protocol_run(tmp_path_factory):
    """One multi-process run of the protocol scenario through the real CLI."""
    run = orchestrate(PROTOCOL, tmp_path_factory.mktemp("protocol"), picture=True)
    assert run.code == 0, run.stderr
    return run, load_scenario(PROTOCOL)


@pytest.fixture(scope="module")
def nav_run(tmp_path_factory):
    """A short in-process run of the nav scenario through the real CLI."""
    run = orchestrate(NAV, tmp_path_factory.mktemp("nav"), "--in-process",
                      "--duration", NAV_DURATION, picture=True)
    assert run.code in (0, 1), run.stderr
    return run, load_scenario(NAV, {"duration": NAV_DURATION})


@pytest.fixture(params=["protocol_run", "nav_run"])
def any_run(request):
    """Each of the two runs."""
    return request.getfixturevalue(request.param)


@pytest.fixture(scope="module")
def bags(protocol_run, nav_run):
    """The decoded bags of both runs, read once: run directory -> BagContents."""
    return {run.run_dir: BagContents(run.run_dir) for run, _ in (protocol_run, nav_run)}


def expected_counts(scenario, ticks: int) -> dict[str, int]:
    """Messages per topic the schedule calls for in a run of ``ticks`` ticks."""
    assert ticks == scenario.schedule.n_ticks, "the run stopped early"
    counts = {"/clock": ticks}
    for topic in scenario.topics:
        latched = topic in scenario.latched_topics  # once, at the first activation
        counts[topic] = 1 if latched else scenario.schedule.samples(scenario.producer_of(topic),
                                                                   topic)
    return counts


def test_bag_has_every_topic_with_the_schedules_message_count(any_run, bags):
    run, scenario = any_run
    bag = bags[run.run_dir]
    expected = expected_counts(scenario, run.manifest["ticks"])
    assert set(bag.messages) == set(expected) == set(scenario.topics) | {"/clock"}
    assert {t: len(m) for t, m in bag.messages.items()} == expected
    assert dict(bag.channel_counts) == expected
    assert bag.schemas["/clock"] == "rosgraph_msgs/msg/Clock"


def test_log_times_are_the_tick_times_of_each_activation(any_run, bags):
    run, scenario = any_run
    bag = bags[run.run_dir]
    tick_ns = scenario.tick_ns
    for topic, messages in bag.messages.items():
        period = 1 if topic == "/clock" else \
            scenario.schedule.periods[scenario.producer_of(topic)]
        times = [t for t, _ in messages]
        assert times == [k * period * tick_ns for k in range(len(times))], topic
        assert bag.publish_times[topic] == times, topic


def test_messages_deserialise_and_carry_their_tick_time(any_run, bags):
    run, _ = any_run
    bag = bags[run.run_dir]
    for log_time, clock in bag.messages["/clock"]:
        assert clock.clock.sec * 10**9 + clock.clock.nanosec == log_time
    for topic, messages in bag.messages.items():
        for log_time, msg in messages:
            header = getattr(msg, "header", None)
            if header is not None:
                assert header.stamp.sec * 10**9 + header.stamp.nanosec == log_time, topic


def test_nav_bag_holds_a_drive(nav_run, bags):
    run, _ = nav_run
    odom = bags[run.run_dir].messages["/odom"]
    first, last = odom[0][1].pose.pose.position, odom[-1][1].pose.pose.position
    assert (first.x, first.y) == (-3.0, -3.0)
    assert np.hypot(last.x - first.x, last.y - first.y) > 0.5
    scan = bags[run.run_dir].messages["/scan"][0][1]
    assert scan.header.frame_id == "laser" and len(scan.ranges) == 360


def test_manifest_has_what_the_run_needs_to_be_understood_and_repeated(any_run):
    run, scenario = any_run
    m = run.manifest
    assert m["scenario"]["file"].endswith(Path(scenario.file).name)
    assert m["scenario"]["sha256"] == scenario.sha256
    assert m["seed"] == scenario.model.seed
    assert set(m["versions"]) >= {"python", "mujoco", "rclpy", "zenoh"}
    assert re.fullmatch(r"[0-9a-f]{64}", m["digest"])
    assert m["outcome"]["status"] in ("success", "goal_not_met")
    assert {"success", "collisions", "metrics"} <= set(m["outcome"])
    assert m["ticks"] == scenario.schedule.n_ticks
    assert m["sim_time_s"] == pytest.approx((m["ticks"] - 1) * scenario.tick_ns / 1e9)
    assert m["wall_time_s"] > 0 and m["real_time_factor"] > 0 and m["ticks_per_s"] > 0
    assert m["outputs"]["bag"] == "bag" and m["outputs"]["report"] == "report.png"
    assert (run.run_dir / m["outputs"]["bag"]).is_dir()
    assert set(m["nodes"]) == set(scenario.nodes)
    for name, entry in m["nodes"].items():
        assert entry["ticks"] == scenario.schedule.activations(name)


def test_multi_process_manifest_has_each_nodes_cost(protocol_run):
    run, _ = protocol_run
    m = run.manifest
    assert m["transport"] == "ros2"
    for entry in [*m["nodes"].values(), m["orchestrator"]]:
        # PSS and USS of each process at one instant (just before the nodes stop): a page
        # forked nodes share with the orchestrator counted once when PSS is summed
        assert 0 < entry["end_uss_mb"] <= entry["end_pss_mb"] <= entry["peak_rss_mb"] + 1
    for entry in m["nodes"].values():
        assert entry["cpu_s"] > 0 and entry["peak_rss_mb"] > 0
        assert 0 < entry["step_ms_mean"] <= entry["step_ms_worst"]
        split = entry["time_s"]  # where the node's run loop spent its wall time
        parts = [split[p] for p in PARTS]
        assert all(v >= 0 for v in parts) and split["step"] > 0 and split["publish"] > 0
        assert sum(parts) + split["other"] == pytest.approx(split["run"], abs=1e-3)
        # the step time the node reported covers its step and serialising
        steps = entry["step_ms_mean"] * entry["ticks"] / 1e3
        assert steps == pytest.approx(split["step"] + split["serialise"], rel=0.05, abs=1e-3)


def test_nav_manifest_has_the_navigation_metrics(nav_run):
    run, scenario = nav_run
    m = run.manifest
    assert m["transport"] == "in-process"
    assert {"time_to_goal", "path_length", "collisions"} <= set(m["outcome"]["metrics"])
    assert m["scenario"]["world"]["file"] == str(scenario.world)


def test_report_png_exists_and_is_not_blank(any_run):
    from matplotlib import image

    run, _ = any_run
    pixels = image.imread(run.run_dir / "report.png")
    assert pixels.shape[0] > 400 and pixels.shape[1] > 800
    assert pixels[..., :3].std() > 0.05
    assert (pixels[..., :3] < 0.5).mean() > 0.01  # ink, not only a white page


def test_summary_is_plain_text_off_a_terminal_and_ends_with_the_final_line(protocol_run):
    run, scenario = protocol_run
    lines = run.stdout.splitlines()
    assert "\x1b[" not in run.stdout
    match = FINAL_LINE.match(lines[-1])
    assert match and match[1] == "success" and Path(match[4]) == run.run_dir
    assert match[2] == run.manifest["digest"]
    text = run.stdout
    for expected in ["Outcome:", "Nodes:", "Outputs:", "report.png", "mean step ms",
                     str(run.run_dir / "manifest.json")]:
        assert expected in text
    for name in scenario.nodes:
        assert re.search(rf"^\s+{name}\s+\d+", text, re.M), name


def fake_outcome(tmp_path, **changes):
    """A RunOutcome-like object for the printing functions."""
    result = SimpleNamespace(digest="ab" * 32, ticks=10, metrics={"control": {
        "goal_reached": 1.0, "time_to_goal": 3.5, "path_length": 2.0, "min_clearance": 0.4}})
    fields = dict(status="success", run_dir=tmp_path, result=result, error=None, wall_s=1.234,
                  start_s=0.5, loop_s=0.7, bag=None, report=None, success=True, collisions=0,
                  node_stats={}, digest="ab" * 32)
    fields.update(changes)
    return SimpleNamespace(**fields)


def test_quiet_prints_only_the_final_line(tmp_path, capsys):
    print_outcome(fake_outcome(tmp_path), quiet=True)
    out, err = capsys.readouterr()
    assert out == f"success: digest {'ab' * 32} (1.23 s) -> {tmp_path}\n"
    assert err == ""


def test_the_error_goes_to_stderr_once_and_the_summary_shows_metrics(tmp_path, capsys):
    outcome = fake_outcome(tmp_path, status="failed", success=False, result=None, digest=None,
                           error="node physics failed at tick 3: boom")
    print_outcome(outcome)
    out, err = capsys.readouterr()
    assert err.count("boom") == 1 and "boom" not in out
    assert out.splitlines()[-1] == f"failed: digest - (1.23 s) -> {tmp_path}"
    print_outcome(fake_outcome(tmp_path))
    out, _ = capsys.readouterr()
    assert re.search(r"time to goal\s+3.50 s", out) and re.search(r"min clearance\s+0.400", out)


def test_progress_is_silent_when_disabled_and_cheap_when_enabled(capsys):
    from rich.console import Console

    quiet = Progress(1000, 10_000_000, enabled=False)
    quiet.update(5)
    quiet.close()
    assert capsys.readouterr() == ("", "")
    sink = io.StringIO()
    shown = Progress(100_000, 10_000_000, enabled=True,
                     console=Console(file=sink, force_terminal=True, width=120))
    shown.update(0)  # opens the bar
    redraws = []
    draw = shown._bar.update
    shown._bar.update = lambda *a, **k: (redraws.append(1), draw(*a, **k))
    started = time.monotonic()
    for k in range(1, 100_000):
        shown.update(k)
    elapsed = time.monotonic() - started
    time.sleep(0.12)
    shown.update(50_000)  # past the redraw interval: the rate is known now
    time.sleep(0.25)  # the display redraws on its own at 10 Hz
    shown.close()
    # cheap: a tick only compares the clock; the bar is touched once per redraw interval
    assert len(redraws) <= elapsed / REDRAW_S + 2
    assert "tick" in sink.getvalue() and "real time" in sink.getvalue()


def test_no_bag_no_picture(tmp_path):
    assert write_report_png(load_scenario(PROTOCOL), tmp_path, None) is None
    assert write_report_png(load_scenario(PROTOCOL), tmp_path, tmp_path / "missing") is None
    assert not (tmp_path / "report.png").exists()


def test_manifest_has_a_digest_per_topic_and_the_digest_without_rendered_topics(any_run):
    """Per-topic digests, recomputed here from the MCAP file with another reader: sha256 over
    (tick, length, bytes) of each message; the rendered topics (the camera's images) are
    named, the digest without them covers every other topic, and the versions a digest
    depends on name the renderer exactly when images are covered."""
    import hashlib
    import struct

    run, scenario = any_run
    m = run.manifest
    hashes: dict[str, hashlib._Hash] = {}
    with sorted((run.run_dir / "bag").glob("*.mcap"))[0].open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=True):
            if channel.topic != "/clock":
                h = hashes.setdefault(channel.topic, hashlib.sha256())
                h.update(struct.pack("<qQ", message.log_time // scenario.tick_ns,
                                     len(message.data)))
                h.update(message.data)
    assert m["topic_digests"] == {t: h.hexdigest() for t, h in sorted(hashes.items())}
    has_camera = "camera" in scenario.nodes
    rendered = ["/camera/color/image_raw", "/camera/depth/image_rect"] if has_camera else []
    assert m["rendered_topics"] == rendered
    whole = hashlib.sha256()
    for topic, digest in sorted(m["topic_digests"].items()):
        if topic not in rendered:
            whole.update(topic.encode() + b"\0" + bytes.fromhex(digest))
    assert m["digest_without_rendered"] == whole.hexdigest()
    versions = m["digest_versions"]
    assert {"python", "numpy", "mujoco", "machine"} <= set(versions)
    assert ("renderer" in versions) == has_camera
    if has_camera:
        assert versions["renderer"].startswith("egl: ") and "unknown" not in versions["renderer"]


def test_no_picture_draws_none_and_says_so(tmp_path):
    """--no-picture (a suite of many short runs): no report.png, the manifest's report is
    null and the summary says "not drawn"; the digest is the one a drawn run has."""
    bare = orchestrate(PROTOCOL, tmp_path / "bare", "--in-process")
    drawn = orchestrate(PROTOCOL, tmp_path / "drawn", "--in-process", picture=True)
    assert bare.code == drawn.code == 0, bare.stderr + drawn.stderr
    assert not (bare.run_dir / "report.png").exists() and (drawn.run_dir / "report.png").exists()
    assert bare.manifest["outputs"]["report"] is None
    assert "not drawn" in bare.stdout
    assert bare.manifest["digest"] == drawn.manifest["digest"]
