"""The README's walk-through of writing your own node works as written, from a directory of
the user's own holding a package of their own, with the installed command (whose
interpreter does not put the working directory on sys.path): in the orchestrator and in
every node process, forked or spawned."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import ROOT

COMMAND = Path(sys.executable).parent / "cosim-orchestrate"  # the installed entry point


def walk_through() -> dict[str, str]:
    """File name -> text of every fenced block of the README's 'Writing your own node'
    whose first line is a comment naming its file."""
    page = (ROOT / "docs" / "tutorials" / "own-node.md").read_text()
    section = page[page.index("## Writing your own node\n"):]
    end = section.find("\n## ", 1)
    section = section[:end] if end > 0 else section
    files = {}
    for block in re.findall(r"```\w*\n(.*?)```", section, re.S):
        first = block.splitlines()[0]
        if found := re.match(r"# (\S+\.(?:py|yaml))", first):
            files[found.group(1)] = block
    return files


def test_the_walk_through_names_its_files():
    assert set(walk_through()) == {"mypkg/mymod.py", "my_scenario.yaml"}


@pytest.mark.parametrize("where, how", [
    ("cwd", "--in-process"), ("cwd", "fork"), ("cwd", "exec"), ("scenario dir", "exec")])
def test_a_package_of_your_own_loads_from_your_directory(tmp_path, where, how):
    # the package and the scenario in the working directory, or both in a folder of their
    # own run from elsewhere
    scenario_dir = tmp_path / "project"
    for name, text in walk_through().items():
        path = scenario_dir / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    (scenario_dir / "mypkg" / "__init__.py").write_text("")
    cwd = scenario_dir if where == "cwd" else tmp_path
    options = ["--in-process"] if how == "--in-process" else ["--spawn", how]
    assert shutil.which(str(COMMAND)), COMMAND
    done = subprocess.run([str(COMMAND), str(scenario_dir / "my_scenario.yaml"), "--duration",
                           "200ms", "--out", str(tmp_path / "runs"), "--quiet", *options],
                          cwd=cwd, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("success: digest "), done.stdout


def test_the_readmes_check_node_example_passes_on_the_walk_through_package(tmp_path):
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Your own node, checked"):]
    example = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    for name, body in walk_through().items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(body)
    (tmp_path / "mypkg" / "__init__.py").write_text("")
    done = subprocess.run([sys.executable, "-c", example], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().startswith("check_node(MyNode): all "), done.stdout
    assert done.stdout.strip().endswith("checks passed"), done.stdout
