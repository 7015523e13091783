"""What a newcomer reads is right: the README's examples run as written, the files and
sections a message points to exist, and a message blames what is at fault (#43 item 6)."""

from __future__ import annotations

import importlib.util
import re
import signal
import textwrap

import pytest

from descriptions.load import load_scenario
from orchestrator import cosim_orchestrate
from plan.errors import ScenarioError
from tests.helpers import NAV, ROOT

README = "\n".join(p.read_text() for p in sorted((ROOT / "docs").rglob("*.md")))
"""The documentation's text (the README's sections moved to docs/)."""


def section(title: str) -> str:
    """The README's section ``title`` (up to the next heading of any level, outside code)."""
    lines = README[README.index(f" {title}\n"):].splitlines()[1:]
    fenced = False
    for n, line in enumerate(lines):
        fenced ^= line.startswith("```")
        if line.startswith("#") and not fenced:
            return "\n".join(lines[:n])
    return "\n".join(lines)


def test_the_readme_says_a_node_needs_outputs_as_well_as_step():
    text = section("Writing your own node")
    first = text[:text.index("```")]
    assert "`outputs(params)`" in first and "`step(tick, inputs)" in first, first


def test_the_readme_shows_how_to_make_the_arrivals_it_passes(monkeypatch):
    from geometry_msgs.msg import PoseStamped

    import orchestrator.api as api

    block = next(b for b in re.findall(r"```python\n(.*?)```", section(
        "Inputs from outside the run"), re.S) if "Arrivals(" in b)
    calls = []
    monkeypatch.setattr(api, "run", lambda scenario, **kw: calls.append((scenario, kw)))
    exec(compile(block, "README.md", "exec"), {})  # noqa: S102 - the README's own example
    (_, kwargs), = calls
    arrivals = kwargs["external"]
    assert isinstance(arrivals, api.Arrivals) and arrivals.topics == {"/goal_pose": PoseStamped}
    arrivals.put("/goal_pose", PoseStamped())


def test_files_named_in_the_scenarios_headers_exist():
    for scenario in sorted((ROOT / "scenarios").glob("*.yaml")):
        comments = "\n".join(line for line in scenario.read_text().splitlines()
                             if line.startswith("#"))
        for named in re.findall(r"\b(?:plan|nodes|runtime|orchestrator)/[\w/]+\.py\b",
                                comments):
            assert (ROOT / named).is_file(), f"{scenario.name} names {named}, which is not there"


def test_a_remap_error_points_to_a_readme_section_that_exists():
    with pytest.raises(ScenarioError) as info:
        load_scenario(NAV, {"nodes.control.remap./odom": {"a": 1}})
    accepted = info.value.accepted
    named = re.search(r"see (docs/[\w/-]+\.md)", accepted)
    assert named, accepted
    assert (ROOT / named.group(1)).is_file(), named.group(1)
    assert "plan/model.py" in accepted and (ROOT / "plan" / "model.py").is_file()


def test_the_help_does_not_promise_parts_in_every_run():
    epilog = cosim_orchestrate.EPILOG
    assert "what every node published under parts/" not in epilog
    assert "parts/" in epilog and "bag/" in epilog


def test_the_readme_reads_sweep_results_with_what_is_installed():
    text = section("Sweeps: many seeds and parameter values")
    reader = re.search(r"`(\w+)\.parquet\.read_table\(", text)
    assert reader and importlib.util.find_spec(reader.group(1)), text
    assert "Pandas or Polars read it" not in text


def test_the_digest_mismatch_blames_the_renderer_only_when_it_is_the_renderer():
    from orchestrator.outputs.diff import _rendered_hint

    mine = {"rendered_topics": ["/camera/image"], "digest_without_rendered": "aa",
            "digest_versions": {"renderer": "EGL"}}
    only_pixels = _rendered_hint(mine, {"digest_without_rendered": "aa"}, False)
    assert "Only the rendered topics (/camera/image) differ" in only_pixels
    everything = _rendered_hint(mine, {"digest_without_rendered": "bb"}, False)
    assert "more than the renderer changed" in everything and "pixels" not in everything
    unknown = _rendered_hint(mine, None, False)  # --expect-digest alone: which part differs?
    assert "if a run on another machine is the reference" in unknown and "aa" in unknown


def test_physics_for_each_robot_says_it_steps_one_world():
    with pytest.raises(ScenarioError) as info:
        load_scenario(ROOT / "scenarios" / "swarm.yaml", {"nodes.physics.for_each": "robot"})
    err = info.value
    assert err.key.endswith("(physics).for_each"), str(err)
    assert "steps one world for every robot" in err.problem
    assert "cannot be templated" in err.problem and "base_link" not in str(err)


def test_a_twin_scenario_with_no_robot_is_refused(tmp_path, capsys):
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        code = cosim_orchestrate.main([str(ROOT / "scenarios" / "twin.yaml"), "--in-process",
                                       "--out", str(tmp_path / "out")])
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    err = capsys.readouterr().err
    assert code == 2, err
    assert ": twin: " in err and "--twin ws://HOST:PORT" in err
    assert not (tmp_path / "out").exists()


def test_a_scenario_with_an_unknown_kind_lists_only_the_kinds_for_users(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent("""
        name: s
        duration: 1s
        nodes:
          - {name: a, kind: lidar, rate: 10}
    """))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    accepted = info.value.accepted
    assert "physics" in accepted and "sensors" in accepted
    assert not re.search(r"\b(counter|faulty|integrator|wallclock)\b", accepted), accepted
