"""Every command's exit code means what its table says: an exception never leaves a command
with 1 ("the goal was not met") or 3 ("a node failed"). What a user can fix is exit 2 at
load time; anything unexpected is 70, cosim's fault, with the traceback kept in a file.

Failures are injected inside this process (each command's main(argv) is called here), so no
transport is involved and each case costs milliseconds.
"""

from __future__ import annotations

import re
import signal
import textwrap
from pathlib import Path

import pytest

from orchestrator import cosim_orchestrate
from orchestrator.sweep import cli as sweep_cli
from runtime import cosim_node
from runtime.entry import EXIT_INTERNAL_ERROR
from tests.helpers import NAV, ROOT

TINY = """
name: tiny
duration: 100ms
nodes:
  - name: a
    kind: counter
    rate: 100
    params: {output: /a}
"""


@pytest.fixture(autouse=True)
def _keep_this_process(monkeypatch):
    """main() installs signal handlers and names the process: undo both here."""
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    monkeypatch.setattr("runtime.parent.name_this_process", lambda _name: None)
    monkeypatch.delenv("COSIM_PARENT_PID", raising=False)
    yield
    for sig, handler in handlers.items():
        signal.signal(sig, handler)


def tiny(tmp_path: Path, text: str = TINY) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def internal_error_file(stderr: str) -> Path:
    """The file the last line names; it holds the traceback."""
    last = stderr.strip().splitlines()[-1]
    assert "internal error (exit 70)" in last and "fault of cosim" in last, stderr
    found = re.search(r"also in (\S+):", last)
    assert found, last
    path = Path(found.group(1))
    assert "Traceback" in path.read_text()
    path.unlink()
    return path


def boom(*_args, **_kwargs):
    raise RuntimeError("injected")


# ---------------------------------------------------------------- cosim-orchestrate


def test_orchestrate_an_unexpected_exception_in_the_run_is_70_not_1(tmp_path, monkeypatch,
                                                                   capsys):
    monkeypatch.setattr("orchestrator.execute.execute", boom)
    code = cosim_orchestrate.main([str(tiny(tmp_path)), "--in-process", "--out",
                                   str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == EXIT_INTERNAL_ERROR == 70, err
    assert "RuntimeError: injected" in err
    internal_error_file(err)


def test_orchestrate_an_unexpected_exception_while_loading_is_70(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("plan.load.resolve", boom)
    code = cosim_orchestrate.main([str(tiny(tmp_path)), "--in-process", "--out",
                                   str(tmp_path / "out")])
    assert code == 70
    internal_error_file(capsys.readouterr().err)
    assert not (tmp_path / "out").exists()


def test_orchestrate_out_naming_an_existing_file_is_bad_input(tmp_path, capsys):
    file = tmp_path / "taken"
    file.write_text("mine")
    for out in (file, file / "below"):
        code = cosim_orchestrate.main([str(tiny(tmp_path)), "--in-process", "--out", str(out)])
        err = capsys.readouterr().err
        assert code == 2, err
        assert f"--out {out}" in err and "is a file" in err and "Traceback" not in err
    assert file.read_text() == "mine"


def test_every_front_end_refuses_out_naming_a_file_before_anything(tmp_path):
    from orchestrator.api import run

    file = tmp_path / "taken"
    file.write_text("mine")
    with pytest.raises(ValueError, match="is a file"):
        run(tiny(tmp_path), in_process=True, out=file, picture=False)
    assert file.read_text() == "mine"


def test_orchestrate_prefix_program_not_on_path_is_bad_input(tmp_path, capsys):
    path = tiny(tmp_path, TINY + "    prefix: no-such-debugger-xyz --args\n")
    code = cosim_orchestrate.main([str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "nodes[0] (a).prefix" in err and "no-such-debugger-xyz" in err
    assert not (tmp_path / "out").exists()
    # an in-process run has no processes to wrap: the prefix is not used there
    assert cosim_orchestrate.main([str(path), "--in-process", "--quiet", "--out",
                                   str(tmp_path / "out")]) == 0


@pytest.mark.parametrize("body, says", [
    ("""
    def step(self, tick, inputs):
        return {}
""", "does not implement outputs(params)"),
    ("""
    @classmethod
    def outputs(cls, params):
        return {}
""", "does not implement step(tick, inputs)"),
    ("""
    @classmethod
    def outputs(cls, params):
        return {"/x": undefined_name}

    def step(self, tick, inputs):
        return {}
""", "raised NameError in outputs(params)"),
])
def test_orchestrate_a_node_class_without_the_contract_is_bad_input(tmp_path, monkeypatch,
                                                                     capsys, body, says):
    name = "half_" + re.sub(r"\W", "_", tmp_path.name)  # a package of each test's own
    pkg = tmp_path / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "half.py").write_text("from nodes.contract import StepNode\n\n\n"
                                 "class Half(StepNode):\n" + textwrap.dedent(body).replace(
                                     "\n", "\n    ").rstrip() + "\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    path = tiny(tmp_path, TINY.replace("kind: counter", f"module: {name}.half:Half")
                .replace("params: {output: /a}", "params: {}"))
    code = cosim_orchestrate.main([str(path), "--in-process", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "nodes[0] (a).module" in err and says in err and "Traceback" not in err


# ---------------------------------------------------------------- cosim-node


def test_node_an_unexpected_exception_is_70_not_1(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(cosim_node, "run_lockstep", boom)
    code = cosim_node.main(["counter", "--scenario", str(tiny(tmp_path))])
    err = capsys.readouterr().err
    assert code == 70, err
    internal_error_file(err)


def test_node_of_another_kind_than_the_one_given_is_bad_input(capsys):
    code = cosim_node.main(["physics", "--scenario", str(NAV), "--node", "lidar"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "node 'lidar' is of kind 'sensors', not 'physics'" in err
    assert "cosim-node sensors --scenario" in err


def test_node_kind_any_takes_any_named_node(monkeypatch):
    ran = []
    monkeypatch.setattr(cosim_node, "run_lockstep", lambda _s, name, *_a: ran.append(name) or 0)
    assert cosim_node.main(["any", "--scenario", str(NAV), "--node", "lidar"]) == 0
    assert cosim_node.main(["sensors", "--scenario", str(NAV), "--node", "lidar"]) == 0
    assert ran == ["lidar", "lidar"]
    # a process of packed nodes (--pack robot, spawned) is named by its first node's kind
    monkeypatch.setattr(cosim_node, "run_packed", lambda _s, names, *_a: ran.append(names) or 0)
    assert cosim_node.main(["physics", "--scenario", str(NAV), "--node", "physics",
                            "--node", "lidar"]) == 0
    assert ran[-1] == ["physics", "lidar"]


# ---------------------------------------------------------------- cosim-sweep


def test_sweep_an_unexpected_exception_is_70_not_1(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sweep_cli, "_sweep", boom)
    code = sweep_cli.main([str(tiny(tmp_path)), "--seeds", "1", "--out", str(tmp_path / "s")])
    err = capsys.readouterr().err
    assert code == 70, err
    internal_error_file(err)


def test_sweep_out_naming_an_existing_file_is_bad_input(tmp_path, capsys):
    file = tmp_path / "taken"
    file.write_text("mine")
    code = sweep_cli.main([str(tiny(tmp_path)), "--seeds", "1", "--out", str(file)])
    assert code == 2, capsys.readouterr().err


# ---------------------------------------------------------------- the documentation


def test_every_command_documents_70_and_the_readme_table_has_every_code():
    for epilog in (cosim_orchestrate.EPILOG, sweep_cli.EPILOG, cosim_node.EPILOG):
        assert "\n  70   internal error" in epilog
    docs = "\n".join(p.read_text() for p in sorted((ROOT / "docs").rglob("*.md")))
    table = docs[docs.index("| code | `cosim-orchestrate`"):]
    table = table[:table.index("\n\n")]
    documented = {int(m) for m in re.findall(r"^\| (\d+) \|", table, re.M)}
    in_help = {int(m) for m in re.findall(r"^  (\d+) ", cosim_orchestrate.EPILOG, re.M)}
    assert in_help | {0, 1, 2, 3, 4, 70, 130} <= documented, documented



@pytest.mark.parametrize("spawn", ["fork", "exec"])
def test_a_node_whose_own_setup_raises_failed_it_is_not_cosims_fault(tmp_path, spawn):
    """The node's code raising is the node failing (its exit 1, the run's 3), spawned or
    forked; never the internal-error code."""
    from tests.helpers import orchestrate

    path = tiny(tmp_path, TINY.replace("kind: counter", "kind: faulty").replace(
        "params: {output: /a}", "params: {output: /a, mode: setup}"))
    run = orchestrate(path, tmp_path / "out", "--spawn", spawn, timeout=120)
    assert run.code == 3, run.stderr
    assert "node a died at start (exit code 1)" in run.stderr
    assert "RuntimeError: injected failure in setup" in run.stderr
    assert "internal error" not in run.stderr
