"""Every way a scenario can be wrong is refused before anything starts, with a clear message.

Each test writes a small YAML file into tmp_path and checks the ScenarioError's text: the
file, the key path and what would be accepted. Only the counter and integrator test kinds
are used, so no world file is needed.
"""

import textwrap
from fractions import Fraction
from pathlib import Path

import pytest

from descriptions.load import load_scenario
from plan.errors import ScenarioError
from plan.timeutil import NS_PER_S

VALID = """
name: pair
seed: 3
duration: 1s
nodes:
  - name: a
    kind: counter
    rate: 100
    params: {output: /a, noise: 5}
  - name: b
    kind: integrator
    rate: 50
    params: {output: /b, gain: 2.0, initial: 0.5}
    inputs:
      - {topic: /a, mode: same_tick}
"""


def write(tmp_path, text, name="scenario.yaml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def refused(tmp_path, text, overrides=None, name="scenario.yaml") -> ScenarioError:
    """Load the text and return the ScenarioError, checking it is one clean paragraph."""
    path = write(tmp_path, text, name)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, overrides)
    err = info.value
    message = str(err)
    assert message.startswith(str(path) + ":"), message
    assert "\n" not in message and "Traceback" not in message
    # no chained traceback behind the message
    assert err.__cause__ is None and (err.__context__ is None or err.__suppress_context__)
    return err


def check(err: ScenarioError, key: str, *words: str, accepted: tuple[str, ...] = ()):
    message = str(err)
    assert err.key == key, message
    assert f": {key}: " in message, message
    for word in words:
        assert word in err.problem, message
    assert err.accepted, message
    assert "Accepted: " in message
    for word in accepted:
        assert word in err.accepted, message


# ---------------------------------------------------------------- the file itself


def test_missing_file(tmp_path):
    with pytest.raises(ScenarioError) as info:
        load_scenario(tmp_path / "absent.yaml")
    assert "absent.yaml" in str(info.value) and "does not exist" in str(info.value)


def test_empty_file(tmp_path):
    err = refused(tmp_path, "", name="empty.yaml")
    assert "empty.yaml" in str(err)
    assert "empty" in err.problem
    assert "name, duration and nodes" in err.accepted


def test_comments_only_is_empty(tmp_path):
    err = refused(tmp_path, "# nothing here\n")
    assert "empty" in err.problem


@pytest.mark.parametrize(("text", "kind"), [("- a\n- b\n", "list"), ("just text\n", "str"),
                                            ("42\n", "int")])
def test_not_a_mapping(tmp_path, text, kind):
    err = refused(tmp_path, text)
    assert f"top level is a {kind}, not a mapping" in err.problem
    assert "mapping with keys such as name" in err.accepted


def test_yaml_syntax_error_names_the_line(tmp_path):
    err = refused(tmp_path, "name: t\nduration: 1s\nnodes: [\n  {name: a\n")
    assert "YAML syntax error at line" in err.problem
    assert "valid YAML" in err.accepted


def test_yaml_tab_indentation_names_line_2(tmp_path):
    err = refused(tmp_path, "name: t\n\tduration: 1s\n")
    assert "at line 2" in err.problem


def test_repeated_key_refused_with_both_lines(tmp_path):
    err = refused(tmp_path, VALID + "duration: 2s\n")
    check(err, "duration", "appears twice", "lines 4 and 16", accepted=("each key once",))


def test_repeated_key_inside_a_node(tmp_path):
    err = refused(tmp_path, VALID.replace("rate: 50", "rate: 50\n    rate: 20"))
    check(err, "nodes[1] (b).rate", "appears twice")


@pytest.mark.parametrize(("key", "as_type"), [("on", "bool"), ("1", "int")])
def test_non_text_key_refused(tmp_path, key, as_type):
    err = refused(tmp_path, VALID.replace("{output: /b,", f"{{{key}: 3, output: /b,"))
    check(err, f"nodes[1] (b).params.{key}", "is not text", f"reads it as {as_type}",
          accepted=("quote it",))


# ---------------------------------------------------------------- unknown keys, at every level


@pytest.mark.parametrize(("text", "key", "accepted"), [
    (VALID + "colour: red\n", "colour",
     "name, seed, duration, tick, transport, zenoh, world, goal, joint_goal, robots, "
     "success, deadlines, external, interactive, twin, simulation_interfaces, nodes, events, "
     "spawnables"),
    (VALID.replace("rate: 50", "rate: 50\n    speed: 3"), "nodes[1] (b).speed",
     "name, kind, module, rate, params, inputs, remap, debug, command, external, process, "
     "prefix, for_each, robots"),
    (VALID.replace("mode: same_tick}", "mode: same_tick, qos: 3}"),
     "nodes[1] (b).inputs[0].qos", "topic, mode"),
    (VALID + "goal: {x: 1, y: 2, z: 3}\n", "goal.z",
     "x, y, yaw, position_tolerance, yaw_tolerance"),
    (VALID + "deadlines: {start: 1s, stop: 2s}\n", "deadlines.stop", "start, tick"),
    (VALID + "success: {reach: true}\n", "success.reach",
     "reach_goal, max_collisions, stop_on_goal"),
    (VALID.replace("gain: 2.0", "gian: 2.0"), "nodes[1] (b).params.gian",
     "output, gain, initial"),
    (VALID.replace("noise: 5", "nois: 5"), "nodes[0] (a).params.nois", "output, noise"),
])
def test_unknown_key_lists_the_keys_at_that_level(tmp_path, text, key, accepted):
    err = refused(tmp_path, text)
    name = key.rsplit(".", 1)[-1]
    check(err, key, f"unknown key {name!r}", accepted=(f"keys here are: {accepted}.",))


# ---------------------------------------------------------------- wrong types


@pytest.mark.parametrize(("text", "key", "problem", "accepted"), [
    (VALID.replace("seed: 3", "seed: abc"), "seed", "'abc' is not valid", "whole number"),
    (VALID.replace("seed: 3", "seed: -1"), "seed", "-1 is not valid", ">= 0"),
    (VALID.replace("rate: 50", "rate: fast"), "nodes[1] (b).rate", "not a number", "rate in Hz"),
    (VALID.replace("gain: 2.0", "gain: lots"), "nodes[1] (b).params.gain", "'lots'", "a number"),
    (VALID.replace("noise: 5", "noise: [1]"), "nodes[0] (a).params.noise", "list",
     "whole number"),
    ("name: t\nduration: 1s\nnodes: {a: 1}\n", "nodes", "valid list",
     "a list of mappings, each with keys name, kind"),
    ("name: t\nduration: 1s\nnodes: [foo]\n", "nodes[0]", "mapping",
     "a mapping with keys name, kind"),
    ("name: t\nduration: 1s\nnodes: []\n", "nodes", "at least 1", "list of mappings"),
    (VALID + "goal: here\n", "goal", "mapping", "a mapping with keys x, y"),
    (VALID + "goal: {x: 1, y: north}\n", "goal.y", "'north'", "a number"),
    (VALID.replace("params: {output: /a, noise: 5}", "params: [1, 2]"), "nodes[0] (a).params",
     "mapping", "params: a mapping"),
    (VALID.replace("mode: same_tick", "mode: later"), "nodes[1] (b).inputs[0].mode",
     "'later'", "same_tick"),
    (VALID.replace("{topic: /a,", "{topic: a,"), "nodes[1] (b).inputs[0].topic", "'a'",
     "a ROS 2 topic name"),
    (VALID.replace("name: b", "name: 2b"), "nodes[1] (2b).name", "'2b'", "letters, digits"),
    (VALID.replace("duration: 1s", "duration: true"), "duration", "boolean", "duration"),
    (VALID.replace("name: pair\n", ""), "name", "required key is missing", "letters"),
    (VALID.replace("    rate: 50\n", ""), "nodes[1] (b).rate", "required key is missing",
     "rate in Hz"),
    (VALID.replace("params: {output: /a, noise: 5}", "params: {noise: 5}"),
     "nodes[0] (a).params.output", "required key is missing", "output: text"),
])
def test_wrong_type(tmp_path, text, key, problem, accepted):
    check(refused(tmp_path, text), key, problem, accepted=(accepted,))


# ---------------------------------------------------------------- durations, rates, ticks


@pytest.mark.parametrize(("old", "new", "key", "problem"), [
    ("duration: 1s", "duration: 0s", "duration", "greater than zero"),
    ("duration: 1s", "duration: -1s", "duration", "greater than zero"),
    ("duration: 1s", "duration: -3", "duration", "greater than zero"),
    ("duration: 1s", "duration: .inf", "duration", "finite"),
    ("duration: 1s", "duration: 1.5ns", "duration", "whole number of nanoseconds"),
    ("rate: 50", "rate: 0", "nodes[1] (b).rate", "greater than zero"),
    ("rate: 50", "rate: -50", "nodes[1] (b).rate", "greater than zero"),
    ("seed: 3", "seed: 3\ntick: 0ms", "tick", "greater than zero"),
    ("seed: 3", "seed: 3\ntick: -10ms", "tick", "greater than zero"),
    ("seed: 3", "seed: 3\ndeadlines: {tick: 0}", "deadlines.tick", "greater than zero"),
])
def test_non_positive_times_refused(tmp_path, old, new, key, problem):
    err = refused(tmp_path, VALID.replace(old, new))
    field = key.rsplit(".", 1)[-1]
    check(err, key, problem, accepted=(f"{field}: ",))
    assert "greater than zero" in err.accepted or "rate in Hz" in err.accepted


def test_rate_with_fractional_period_gets_an_exact_tick(tmp_path):
    """30 Hz has a period of 1/30 s, not whole ns: the tick is the exact gcd, 1/300 s with
    100 Hz, and each period a whole number of such ticks."""
    scenario = load_scenario(write(tmp_path, VALID.replace("rate: 50", "rate: 30")))
    assert scenario.tick_ns == Fraction(NS_PER_S, 300)
    assert scenario.schedule.periods == {"a": 3, "b": 10}
    assert scenario.schedule.n_ticks == 301


def test_duration_not_a_multiple_of_a_fractional_tick(tmp_path):
    err = refused(tmp_path, VALID.replace("rate: 50", "rate: 30").replace("duration: 1s",
                                                                          "duration: 1005ms"))
    check(err, "duration", "1005ms", "not a whole number of 1/300s ticks",
          accepted=("multiple of the tick", "1010ms"))


def test_rate_not_a_whole_number_of_ticks_says_which_rates_fit(tmp_path):
    err = refused(tmp_path, VALID.replace("rate: 50", "rate: 40") + "tick: 10ms\n")
    check(err, "nodes[1] (b).rate", "40 Hz", "25ms", "not a whole number of 10ms ticks",
          accepted=("multiple of the 10ms tick", "100, 50, 25, 20 Hz"))


def test_rate_that_fits_no_tick_suggests_another_tick(tmp_path):
    err = refused(tmp_path, VALID[:VALID.index("  - name: b")] + "tick: 3ms\n")
    check(err, "nodes[0] (a).rate", "not a whole number of 3ms ticks",
          accepted=("change the tick", "10ms"))


def test_duration_not_a_multiple_of_the_tick(tmp_path):
    err = refused(tmp_path, VALID.replace("duration: 1s", "duration: 1005ms"))
    check(err, "duration", "1005ms", "not a whole number of 10ms ticks",
          accepted=("multiple of the tick", "1010ms"))


# ---------------------------------------------------------------- files, names, graph


def test_world_file_missing_resolved_next_to_the_scenario(tmp_path):
    sub = tmp_path / "scen"
    sub.mkdir()
    err = refused(sub, VALID + "world: nope.xml\n")
    check(err, "world", "'nope.xml' does not exist", str(sub / "nope.xml"),
          accepted=("relative to the scenario file",))


def test_world_file_found_relative_to_the_scenario(tmp_path):
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "w.xml").write_text("<mujoco/>")
    scenario = load_scenario(write(tmp_path, VALID + "world: worlds/w.xml\n"))
    assert scenario.world == (tmp_path / "worlds" / "w.xml").resolve()


def test_duplicate_node_names(tmp_path):
    err = refused(tmp_path, VALID.replace("name: b", "name: a"))
    check(err, "nodes[1] (a).name", "duplicate node name 'a'", "nodes[0]",
          accepted=("one node only",))


def test_input_topic_nobody_publishes(tmp_path):
    err = refused(tmp_path, VALID.replace("{topic: /a,", "{topic: /zzz,"))
    check(err, "nodes[1] (b).inputs[0].topic", "no node publishes /zzz",
          accepted=("a published topic: /a, /b",))


def test_input_listed_twice(tmp_path):
    text = VALID + "      - {topic: /a, mode: delayed}\n"
    err = refused(tmp_path, text)
    check(err, "nodes[1] (b).inputs[1].topic", "listed twice", accepted=("each topic once",))


def test_same_tick_cycle_named(tmp_path):
    text = VALID.replace("params: {output: /a, noise: 5}",
                         "params: {output: /a}\n    inputs: [{topic: /b, mode: same_tick}]")
    err = refused(tmp_path, text)
    check(err, "nodes", "algebraic loop a -> b -> a", accepted=("mode: delayed",))


def test_delayed_edge_breaks_the_cycle(tmp_path):
    text = VALID.replace("params: {output: /a, noise: 5}",
                         "params: {output: /a}\n    inputs: [{topic: /b, mode: delayed}]")
    scenario = load_scenario(write(tmp_path, text))
    assert scenario.schedule.due(0) == ("a", "b")


def test_three_node_cycle_named(tmp_path):
    text = """
    name: ring
    duration: 1s
    nodes:
      - {name: x, kind: counter, rate: 100, params: {output: /x},
         inputs: [{topic: /z, mode: same_tick}]}
      - {name: y, kind: counter, rate: 100, params: {output: /y},
         inputs: [{topic: /x, mode: same_tick}]}
      - {name: z, kind: counter, rate: 100, params: {output: /z},
         inputs: [{topic: /y, mode: same_tick}]}
    """
    check(refused(tmp_path, text), "nodes", "x -> y -> z -> x")


def test_unknown_node_kind(tmp_path):
    err = refused(tmp_path, VALID.replace("kind: integrator", "kind: integrater"))
    check(err, "nodes[1] (b).kind", "unknown node kind 'integrater'",
          accepted=("physics", "sensors", "control", "module:"))
    for test_kind in ("counter", "faulty", "integrator", "wallclock"):  # the suite's own
        assert test_kind not in err.accepted, str(err)


def test_kind_and_module_both_or_neither(tmp_path):
    err = refused(tmp_path, VALID.replace("    kind: counter\n", ""))
    check(err, "nodes[0] (a)", "exactly one of 'kind', 'module' or 'command'",
          accepted=("physics",))
    text = VALID.replace("kind: counter", "kind: counter\n    module: nodes.testing:CounterNode")
    check(refused(tmp_path, text), "nodes[0] (a)", "exactly one")


def test_module_that_cannot_load(tmp_path):
    err = refused(tmp_path, VALID.replace("kind: counter", "module: nodes.nothere:Thing"))
    check(err, "nodes[0] (a).module", "cannot load 'nodes.nothere:Thing'",
          accepted=("package.module:Class",))


def test_module_given_instead_of_kind(tmp_path):
    scenario = load_scenario(write(tmp_path, VALID.replace(
        "kind: counter", "module: nodes.testing:CounterNode")))
    assert scenario.nodes["a"].class_ref == "nodes.testing:CounterNode"


def test_unknown_transport(tmp_path):
    err = refused(tmp_path, VALID + "transport: dds\n")
    check(err, "transport", "'dds'", accepted=("ros2 or zenoh",))


def test_topic_published_by_two_nodes(tmp_path):
    err = refused(tmp_path, VALID.replace("{output: /b,", "{output: /a,"))
    check(err, "nodes[1] (b)", "topic /a is also published by node 'a'",
          accepted=("one publisher per topic", "remap"))


# ---------------------------------------------------------------- remap


def test_remapped_output_is_published_under_its_new_name(tmp_path):
    text = VALID.replace("rate: 100", "rate: 100\n    remap: {/a: /count}").replace(
        "{topic: /a,", "{topic: /count,")
    scenario = load_scenario(write(tmp_path, text))
    a = scenario.nodes["a"]
    assert set(a.outputs) == {"/count"}
    assert a.output_names == {"/a": "/count"}
    assert set(a.declared_outputs) == {"/a"}
    assert scenario.producer_of("/count") == "a"
    assert "/a" not in scenario.topics
    (inp,) = scenario.nodes["b"].inputs
    assert (inp.topic, inp.graph_topic, inp.producer) == ("/count", "/count", "a")


def test_remapped_input_reads_the_new_name(tmp_path):
    text = VALID.replace("mode: same_tick}", "mode: same_tick}\n    remap: {/a: /a_graph}")
    text = text.replace("{output: /a,", "{output: /a_graph,")
    scenario = load_scenario(write(tmp_path, text))
    (inp,) = scenario.nodes["b"].inputs
    assert (inp.topic, inp.graph_topic, inp.producer) == ("/a", "/a_graph", "a")


def test_remap_of_a_topic_the_node_does_not_have(tmp_path):
    err = refused(tmp_path, VALID.replace("rate: 50", "rate: 50\n    remap: {/nothere: /x}"))
    check(err, "nodes[1] (b).remap./nothere", "no topic '/nothere' to remap",
          accepted=("one of its topics: /a, /b",))


def test_remap_onto_another_nodes_topic_is_two_publishers(tmp_path):
    err = refused(tmp_path, VALID.replace("rate: 50", "rate: 50\n    remap: {/b: /a}"))
    check(err, "nodes[1] (b)", "also published by node 'a'")


# ---------------------------------------------------------------- a valid scenario


def test_valid_scenario_resolves(tmp_path):
    scenario = load_scenario(write(tmp_path, VALID))
    assert scenario.name == "pair"
    assert scenario.model.seed == 3
    assert scenario.tick_ns == 10_000_000  # gcd of 10ms and 20ms
    assert scenario.schedule.n_ticks == 101
    assert scenario.schedule.last_tick == 100
    assert {n: p.period_ticks for n, p in scenario.nodes.items()} == {"a": 1, "b": 2}
    assert list(scenario.nodes) == ["a", "b"]  # file order
    assert scenario.world is None
    assert scenario.topics.keys() == {"/a", "/b"}
    (inp,) = scenario.nodes["b"].inputs
    assert (inp.topic, inp.graph_topic, inp.producer, inp.mode) == ("/a", "/a", "a", "same_tick")
    assert inp.msg_type.__name__ == "Int64"
    assert scenario.nodes["b"].params.gain == 2.0
    assert scenario.nodes["a"].params.noise == 5
    assert scenario.schedule.due(0) == ("a", "b")
    assert scenario.schedule.due(1) == ("a",)
    assert len(scenario.sha256) == 64
    for value in (scenario.tick_ns, scenario.model.duration, scenario.nodes["a"].period_ticks):
        assert type(value) is int


def test_tick_is_gcd_of_periods(tmp_path):
    text = VALID.replace("rate: 100", "rate: 40").replace("rate: 50", "rate: 25")
    scenario = load_scenario(write(tmp_path, text))
    assert scenario.tick_ns == 5_000_000  # gcd(25ms, 40ms)
    assert {n: p.period_ticks for n, p in scenario.nodes.items()} == {"a": 5, "b": 8}


def test_explicit_tick(tmp_path):
    scenario = load_scenario(write(tmp_path, VALID + "tick: 5ms\n"))
    assert scenario.tick_ns == 5_000_000
    assert {n: p.period_ticks for n, p in scenario.nodes.items()} == {"a": 2, "b": 4}
    assert scenario.schedule.n_ticks == 201


# ---------------------------------------------------------------- overrides


def test_overrides(tmp_path):
    path = write(tmp_path, VALID)
    scenario = load_scenario(path, {"seed": 5, "nodes.b.rate": 20})
    assert scenario.model.seed == 5
    assert scenario.nodes["b"].period_ticks == 5
    assert scenario.overrides == {"seed": 5, "nodes.b.rate": 20}
    assert load_scenario(path).model.seed == 3  # the file is untouched


def test_override_of_a_node_param(tmp_path):
    scenario = load_scenario(write(tmp_path, VALID), {"nodes.b.params.gain": -1.5})
    assert scenario.nodes["b"].params.gain == -1.5


def test_override_naming_no_node(tmp_path):
    err = refused(tmp_path, VALID, {"nodes.zz.rate": 20})
    check(err, "nodes.zz.rate", "override names no node 'zz'", accepted=("a node name: a, b",))


def test_override_with_a_bad_value_says_it_came_from_the_override(tmp_path):
    err = refused(tmp_path, VALID, {"nodes.b.rate": -30})
    check(err, "nodes[1] (b).rate", "-30 Hz", "override nodes.b.rate=-30",
          accepted=("rate in Hz",))


def test_override_with_an_unknown_key(tmp_path):
    err = refused(tmp_path, VALID, {"nodes.b.colour": "red"})
    check(err, "nodes[1] (b).colour", "unknown key 'colour'", "override",
          accepted=("name, kind, module, rate",))


@pytest.mark.parametrize("key", ["", "nodes..rate", "seed."])
def test_override_key_malformed(tmp_path, key):
    err = refused(tmp_path, VALID, {key: 1})
    assert "not a dotted key path" in err.problem
    assert "nodes.<node name>.rate" in err.accepted


def test_override_through_a_scalar(tmp_path):
    err = refused(tmp_path, VALID, {"name.x.y": 1})
    check(err, "name.x.y", "goes through name", "not a mapping")


def test_override_on_the_nodes_list_itself(tmp_path):
    err = refused(tmp_path, VALID, {"nodes.rate": 3})
    check(err, "nodes.rate", "no node 'rate'")


def test_kind_whose_code_cannot_load_is_an_error_not_a_traceback(tmp_path, monkeypatch):
    from nodes import registry
    monkeypatch.setitem(registry.KINDS, "broken", "nodes.not_installed:Thing")
    err = refused(tmp_path, VALID.replace("kind: integrator", "kind: broken"))
    check(err, "nodes[1] (b).kind", "'broken' cannot be loaded", "nodes.not_installed",
          accepted=("installed",))


# ---------------------------------------------------------------- found at load, not at start


def test_empty_special_file_is_empty_not_missing():
    with pytest.raises(ScenarioError) as info:
        load_scenario("/dev/null")
    assert "does not exist" not in str(info.value)
    assert info.value.problem == "the file is empty."


def test_physics_period_not_a_whole_number_of_timesteps_is_bad_input(tmp_path):
    """nav's world has a 2 ms timestep: a 1 ns physics period is refused at load time (exit
    2, no run directory), not by the physics node once the run has started (exit 3)."""
    from tests.helpers import SCENARIOS, orchestrate

    nav = SCENARIOS.parent.parent / "scenarios" / "nav.yaml"
    for args in (["--set", "nodes.physics.rate=1000000000"], ["--set", "nodes.physics.rate=400"],
                 ["--set", "nodes.physics.rate=30"]):  # 1/30 s: no whole number of 2 ms steps
        proc = orchestrate(nav, tmp_path / "runs", *args, "--duration", "1s")
        assert proc.code == 2, proc.stderr
        assert "nodes[0] (physics).rate" in proc.stderr and "2000000 ns" in proc.stderr
        assert "Traceback" not in proc.stderr
        assert not (tmp_path / "runs").exists()
    proc = orchestrate(Path("/dev/null"), tmp_path / "runs")
    assert proc.code == 2 and "the file is empty" in proc.stderr, proc.stderr
    assert not (tmp_path / "runs").exists()


def refused_all(tmp_path, text) -> ScenarioError:
    """Load the text; the ScenarioError naming every problem, one per numbered line."""
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    lines = str(err).splitlines()
    assert lines[0] == f"{path}: {len(err.errors)} problems:", str(err)
    for n, (line, one) in enumerate(zip(lines[1:], err.errors, strict=True), 1):
        assert line == f"  {n}. {one.key}: {one.problem} Accepted: {one.accepted}"
        assert one.file == str(path) and one.accepted
    return err


def test_independent_mistakes_are_all_reported_in_one_error(tmp_path):
    err = refused_all(tmp_path, VALID.replace("seed: 3", "seed: 3\ncolour: red\nworld: "
                                              "nowhere.xml\ntick: 20ms")
                      .replace("{topic: /a,", "{topic: /nowhere,"))
    assert [e.key for e in err.errors] == ["colour", "world", "nodes[0] (a).rate",
                                           "nodes[1] (b).inputs[0].topic"]
    words = ["unknown key 'colour'", "'nowhere.xml' does not exist",
             "not a whole number of 20ms ticks", "no node publishes /nowhere"]
    for one, word in zip(err.errors, words, strict=True):
        assert word in one.problem, str(err)
    assert err.key == "colour"  # the first, for callers that read one


def test_every_wrong_parameter_and_input_of_a_node_is_reported(tmp_path):
    err = refused_all(tmp_path, VALID.replace("gain: 2.0, initial: 0.5", "gain: x, initial: y")
                      .replace("params: {output: /a, noise: 5}",
                               "params: {output: /a, noise: 5, size: 1}"))
    assert [e.key for e in err.errors] == ["nodes[0] (a).params.size",
                                           "nodes[1] (b).params.gain",
                                           "nodes[1] (b).params.initial"], str(err)
    inputs = refused_all(tmp_path, VALID.replace(
        "      - {topic: /a, mode: same_tick}",
        "      - {topic: /x, mode: same_tick}\n      - {topic: /y, mode: same_tick}"))
    assert [e.problem for e in inputs.errors] == ["no node publishes /x.",
                                                  "no node publishes /y."]


def test_a_mistake_is_not_reported_again_through_what_it_breaks(tmp_path):
    # an unknown kind: the node's topics are unknown, so b's input from it is not blamed
    err = refused(tmp_path, VALID.replace("kind: counter", "kind: countr"))
    check(err, "nodes[0] (a).kind", "unknown node kind 'countr'")
    assert len(err.errors) == 1


def test_the_command_line_prints_every_problem_and_starts_nothing(tmp_path):
    import subprocess

    from tests.helpers import ORCHESTRATE, ROOT

    path = write(tmp_path, VALID.replace("seed: 3", "seed: 3\ncolour: red\ntick: 20ms")
                 .replace("{topic: /a,", "{topic: /nowhere,"))
    out = tmp_path / "runs"
    run = subprocess.run([*ORCHESTRATE, str(path), "--out", str(out)], capture_output=True,
                         text=True, timeout=120, cwd=ROOT)
    assert run.returncode == 2, run.stderr
    assert f"{path}: 3 problems:" in run.stderr
    for line in ("  1. colour: unknown key 'colour'.", "  2. nodes[0] (a).rate: a rate of 100",
                 "  3. nodes[1] (b).inputs[0].topic: no node publishes /nowhere."):
        assert line in run.stderr, run.stderr
    assert not out.exists()
