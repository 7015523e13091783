"""The run's rules hold whoever starts the run: the command line, the Python API and the
pytest plugin refuse the same scenarios, apply the scenario's zenoh section, and show the
scenario's warnings."""

from __future__ import annotations

import socket
import warnings

import pytest
import yaml

from orchestrator.api import ScenarioError, ScenarioWarning, run
from tests.helpers import SCENARIOS, orchestrate

ECHO = SCENARIOS / "foreign_echo.yaml"
PROTOCOL = SCENARIOS / "protocol.yaml"


def variant(tmp_path, source, **changes):
    doc = yaml.safe_load(source.read_text())
    doc.update(changes)
    for node in doc["nodes"]:  # keep the foreign program's relative path working
        if node.get("command"):
            node["command"] = [str((source.parent / a).resolve()) if a.startswith("..") else a
                               for a in node["command"]]
    path = tmp_path / source.name
    path.write_text(yaml.safe_dump(doc))
    return path


def with_unread_remap(tmp_path):
    doc = yaml.safe_load(PROTOCOL.read_text())
    doc["duration"] = "100ms"
    doc["nodes"][4]["remap"] = {"/slow": "/slow_unread"}  # 'slow' feeds 'middle' no more
    doc["nodes"][1]["inputs"] = [{"topic": "/source", "mode": "same_tick"}]
    path = tmp_path / "remapped.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture
def busy_port():
    """A loopback port held open, so a zenoh session told to listen there cannot."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen()
    yield sock.getsockname()[1]
    sock.close()


# -- the command line -------------------------------------------------------------------

def test_cli_refuses_foreign_programs_over_zenoh_and_in_process(tmp_path):
    zenoh = orchestrate(variant(tmp_path, ECHO, transport="zenoh"), tmp_path / "a")
    assert zenoh.code == 2 and "foreign ROS 2 programs" in zenoh.stderr, zenoh.stderr
    inproc = orchestrate(ECHO, tmp_path / "b", "--in-process")
    assert inproc.code == 2 and "in-process runs step classes only" in inproc.stderr
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_cli_prints_the_scenario_warnings(tmp_path):
    done = orchestrate(with_unread_remap(tmp_path), tmp_path / "runs", "--in-process")
    assert done.code == 0, done.stderr
    assert "warning:" in done.stderr and "/slow_unread" in done.stderr


# -- the Python API ---------------------------------------------------------------------

def test_api_refuses_what_the_cli_refuses(tmp_path):
    with pytest.raises(ScenarioError, match="foreign ROS 2 programs"):
        run(variant(tmp_path, ECHO, transport="zenoh"), out=tmp_path / "a", picture=False)
    with pytest.raises(ScenarioError, match="in-process runs step classes only"):
        run(ECHO, in_process=True, out=tmp_path / "b", picture=False)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_api_issues_the_scenario_warnings(tmp_path):
    with pytest.warns(ScenarioWarning, match="/slow_unread"):
        result = run(with_unread_remap(tmp_path), in_process=True, out=tmp_path / "runs",
                     picture=False)
    assert result.manifest["warnings"] and "/slow_unread" in result.manifest["warnings"][0]


def test_api_applies_the_scenarios_zenoh_section(tmp_path, busy_port):
    # listening where the port is taken fails the run; a run that ignored the section would
    # listen on a free port and succeed
    path = variant(tmp_path, PROTOCOL, transport="zenoh", duration="100ms",
                   zenoh={"listen": [f"tcp/127.0.0.1:{busy_port}"]})
    result = run(path, out=tmp_path / "runs", check=False, picture=False)
    assert result.status == "failed" and str(busy_port) in (result.error or ""), result.error


# -- the pytest plugin --------------------------------------------------------------------

def test_plugin_refuses_and_warns_like_the_api(tmp_path, cosim):
    with pytest.raises(ScenarioError, match="foreign ROS 2 programs"):
        cosim.run(variant(tmp_path, ECHO, transport="zenoh"))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        cosim.run(with_unread_remap(tmp_path), in_process=True, golden=False)
    assert any(issubclass(w.category, ScenarioWarning) for w in seen)


def test_one_foreign_program_feeding_another_is_refused(tmp_path):
    doc = yaml.safe_load(ECHO.read_text())
    second = dict(doc["nodes"][1], name="echo2", remap={"/in": "/echoed", "/out": "/twice"})
    doc["nodes"].insert(2, second)
    path = variant(tmp_path, ECHO, nodes=doc["nodes"])
    done = orchestrate(path, tmp_path / "r")
    assert done.code == 2, done.stderr
    assert "nodes[2] (echo2).inputs" in done.stderr
    assert "/echoed comes from foreign program 'echo'" in done.stderr
    assert not (tmp_path / "r").exists()


def test_a_program_is_gated_when_a_gate_serves_it(tmp_path, monkeypatch):
    """One rule (plan.gates, the node's role) for the proxy, the checks and the run rules: a
    program that is not Python is gated by the RMW gate where it is built; without it, it is
    ungated, and with two inputs refused before anything starts."""
    import plan.gates
    from descriptions.load import load_scenario
    from plan.roles import NodeRole

    doc = yaml.safe_load((SCENARIOS / "foreign_fusion.yaml").read_text())
    doc["nodes"][3]["command"] = ["cat"]
    path = tmp_path / "fusion_cat.yaml"
    path.write_text(yaml.safe_dump(doc))
    python = variant(tmp_path, SCENARIOS / "foreign_fusion.yaml")
    assert plan.gates.rmw_gate_library().is_file(), "make install builds the RMW gate"
    cat = load_scenario(path).nodes["fusion"]
    assert (cat.gate, cat.role) == ("rmw", NodeRole.RMW_GATE)
    assert load_scenario(python).nodes["fusion"].gate == "python"
    monkeypatch.setattr(plan.gates, "rmw_gate_library", lambda: tmp_path / "not-built.so")
    cat = load_scenario(path).nodes["fusion"]
    assert (cat.gate, cat.role, cat.role.is_gated) == (None, NodeRole.UNGATED, False)
    with pytest.raises(ScenarioError, match="the RMW gate that serves other languages is not "
                                            "built"):
        run(path, out=tmp_path / "r", picture=False)
    assert not (tmp_path / "r").exists()
    # the Python gate needs no build
    assert load_scenario(python).nodes["fusion"].role is NodeRole.PYTHON_GATE


# -- the rules themselves ------------------------------------------------------------------

def test_every_rule_is_a_named_check_with_a_docstring():
    from orchestrator.run_rules import FOREIGN_RULES, RULES

    names = [r.name for r in [*RULES, *FOREIGN_RULES]]
    assert len(names) == len(set(names)) >= 10, names
    assert all(r.doc.strip() for r in [*RULES, *FOREIGN_RULES])
    assert names[:2] == ["in_process_runs_step_classes", "zenoh_carries_cosim_nodes"]
