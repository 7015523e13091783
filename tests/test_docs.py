"""The documentation site (docs/, mkdocs.yml): it builds with no warning (dead links, pages
missing from the nav, broken anchors), its generated reference is the code's, and the
commands of its tutorials run as written.

A tutorial marks what the reader types as a ```console block of ``$ command`` lines. Each
block is run here with bash, in a directory that holds the repository's files, the cosim
commands standing for the installed ones: a ``$ command &`` runs in the background for the
rest of the block and is stopped (SIGINT) after it. Every command exits 0, unless the comment
before the block says ``<!-- test: exit N -->``: then each cosim run of the block (a
cosim-orchestrate or cosim-sweep command) exits N, and the paragraph after the block says so
("exit N" or "exits N") where the reader sees it. A block that cannot run here says why in
the comment before it: ``<!-- test: skip: REASON -->``.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.helpers import ROOT

DOCS = ROOT / "docs"
TUTORIALS = ["getting-started.md", *sorted(p.relative_to(DOCS).as_posix()
                                          for p in (DOCS / "tutorials").glob("*.md")),
             "concepts/digest.md"]
RUNS = ("cosim-orchestrate", "cosim-sweep")  # what a block's exit code is about


def test_site_builds_with_no_warning(tmp_path):
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                           str(tmp_path / "site")], cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"}, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "WARNING" not in done.stderr, done.stderr
    assert (tmp_path / "site" / "reference" / "scenario" / "index.html").exists()


def test_generated_reference_is_current():
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import gen_reference
    finally:
        sys.path.remove(str(ROOT / "tools"))
    stale = [path.relative_to(ROOT).as_posix() for path, text in gen_reference.generate().items()
             if not path.exists() or path.read_text(encoding="utf-8") != text]
    assert not stale, (f"the generated reference is stale: {stale}; "
                       "run .venv/bin/python tools/gen_reference.py and commit")


def test_the_reference_covers_every_command_and_scenario_key():
    text = (DOCS / "reference" / "cli.md").read_text()
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    for command in scripts:
        assert f"## `{command}`" in text, f"{command} has no section in reference/cli.md"
    assert "`--expect-digest`" in text and "#### `cosim-ros2 topic pub`" in text
    scenario = (DOCS / "reference" / "scenario.md").read_text()
    for key in ("`robots.named[].start`", "| `stale_after` |", "| `for_each` |"):
        assert key in scenario


def test_the_readme_is_short_and_leads_into_the_docs():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 150, "the README grows: move the new material to docs/"
    links = re.findall(r"\]\((?!https?:)([^)#]+)", text)
    assert "docs/getting-started.md" in links and "docs/images/report.png" in links
    missing = [link for link in links if not (ROOT / link).exists()]
    assert not missing, f"README.md links to files that do not exist: {missing}"


def test_the_readme_and_getting_started_name_every_command():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    for page in (ROOT / "README.md", DOCS / "getting-started.md"):
        text = page.read_text()
        missing = [name for name in scripts if f"`{name}`" not in text]
        assert not missing, f"{page.relative_to(ROOT)} does not name {missing}"


def test_the_index_and_the_readme_lead_to_every_page():
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")} - {"index.md"}
    index = set(re.findall(r"\]\(([^)#]+\.md)", (DOCS / "index.md").read_text()))
    readme = {link.removeprefix("docs/") for link in
              re.findall(r"\]\(([^)#]+\.md)", (ROOT / "README.md").read_text())}
    assert not pages - index, f"docs/index.md leaves out {sorted(pages - index)}"
    assert not pages - readme, f"README.md leaves out {sorted(pages - readme)}"


def test_the_readme_lists_every_exit_code_of_cosim_orchestrate():
    from tools.gen_reference import exit_codes

    text = (ROOT / "README.md").read_text()
    table = text.split("| `cosim-orchestrate` | meaning |", 1)[1].split("\n\n", 1)[0]
    listed = {int(code): meaning for code, meaning in
              re.findall(r"^\| (\d+) \| ([^|]+) \|$", table, flags=re.M)}
    codes = exit_codes("orchestrator.cosim_orchestrate")
    assert sorted(listed) == sorted(codes), "README's exit codes differ from EXIT_* constants"
    for code, meaning in codes.items():
        assert listed[code].startswith(meaning), (code, listed[code], meaning)


@dataclass
class Block:
    """One ```console block of a page: its commands and whether (why not) it runs here."""

    page: str
    line: int
    commands: list[str]
    skip: str | None
    exit: int = 0  # what each cosim run of the block exits with, as the page says
    after: str = ""  # the paragraph after the block

    @property
    def id(self) -> str:
        """page:line, the test's id."""
        return f"{self.page}:{self.line}"


def console_blocks(page: str) -> list[Block]:
    """The page's ```console blocks, with the skip reason of the comment before each."""
    lines = (DOCS / page).read_text().splitlines()
    blocks, i = [], 0
    while i < len(lines):
        if lines[i].strip() != "```console":
            i += 1
            continue
        before = lines[i - 1].strip() if i else ""
        skip = re.match(r"<!-- test: skip: (.+) -->$", before)
        code = re.match(r"<!-- test: exit (\d+) -->$", before)
        start, commands, i = i + 1, [], i + 1
        while lines[i].strip() != "```":
            line = lines[i].strip()
            if line.startswith("$ "):
                commands.append(line[2:])
            elif commands and commands[-1].endswith("\\"):
                commands[-1] = commands[-1][:-1] + " " + line
            i += 1
        after = []
        for line in lines[i + 1:]:
            if not line.strip() and after:
                break
            after.append(line.strip())
        blocks.append(Block(page, start, commands, skip.group(1) if skip else None,
                            int(code.group(1)) if code else 0, " ".join(after)))
    return blocks


BLOCKS = [b for page in TUTORIALS for b in console_blocks(page)]


def test_a_block_whose_runs_do_not_exit_0_says_so_after_it():
    for block in BLOCKS:
        if block.exit:
            assert re.search(rf"\bexits? {block.exit}\b", block.after), (
                f"docs/{block.id}: its runs exit {block.exit}, and the paragraph after it "
                f"does not say so: {block.after!r}")


def test_every_tutorial_has_commands_the_suite_runs():
    for page in TUTORIALS:
        runs = [b for b in console_blocks(page) if b.skip is None and b.commands]
        assert runs, f"docs/{page} has no ```console block that the suite runs"


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.skip is None], ids=lambda b: b.id)
def test_tutorial_commands_run_as_written(block, tmp_path):
    work = _workdir(tmp_path)
    script = ["set -u"]
    for n, command in enumerate(block.commands):
        command = command.replace(".venv/bin/", "")
        if command.endswith("&"):  # its output to a file: the block's pipes close at its end
            script.append(f"{command[:-1].rstrip()} > background-{n}.log 2>&1 &")
            continue
        run = command.split()[0].split("=")[-1] in RUNS or any(
            f" {c} " in f" {command} " for c in RUNS)
        expected = block.exit if run else 0
        script += [command, "rc=$?",
                   f"if [ $rc -ne {expected} ]; then echo \"exit $rc (the page says "
                   f"{expected}): {_quoted(command)}\" >&2; exit 1; fi"]
    proc = subprocess.Popen(["bash", "-c", "\n".join(script)], cwd=work, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, "PATH": f"{work / 'bin'}:{os.environ['PATH']}"},
                            start_new_session=True)
    try:
        out, err = proc.communicate(timeout=240)
    finally:
        _stop_group(proc.pid)
    background = "".join(f"\n{log.name}:\n{log.read_text()[-2000:]}"
                         for log in sorted(work.glob("background-*.log")))
    assert proc.returncode == 0, f"docs/{block.id}:\n{out[-3000:]}\n{err[-3000:]}{background}"


def _workdir(tmp_path: Path) -> Path:
    """A directory with the repository's files (links) and bin/ holding each cosim command
    and python as this interpreter with this tree first on its path."""
    work = tmp_path / "work"
    work.mkdir()
    for entry in ROOT.iterdir():
        if entry.name not in (".venv", "runs", "build", ".git", "sweeps"):
            (work / entry.name).symlink_to(entry)
    bin_dir = work / "bin"
    bin_dir.mkdir()
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    for name, ref in scripts.items():
        module, function = ref.split(":")
        _executable(bin_dir / name, f"import sys; sys.path.insert(0, {str(ROOT)!r}); "
                                    f"from {module} import {function}; sys.exit({function}())")
    (bin_dir / "python").write_text(f'#!/bin/sh\nexec {sys.executable} "$@"\n')
    (bin_dir / "python").chmod(0o755)
    return work


def _executable(path: Path, code: str) -> None:
    """A shell script running ``code`` with this interpreter and the script's arguments."""
    path.write_text(f'#!/bin/sh\nexec {sys.executable} -c "{code}" "$@"\n')
    path.chmod(0o755)


def _quoted(command: str) -> str:
    """A command made safe inside double quotes of the bash script."""
    return re.sub(r'(["$`\\])', r"\\\1", command)


def _stop_group(pgid: int) -> None:
    """Stop what the block left in the background: SIGINT, then SIGKILL after 15 s. They
    are this process's children by now (the suite is their subreaper), so waiting reaps."""
    import psutil

    def members() -> list[psutil.Process]:
        found = []
        for proc in psutil.process_iter():
            try:
                if os.getpgid(proc.pid) == pgid and proc.status() != psutil.STATUS_ZOMBIE:
                    found.append(proc)
            except (OSError, psutil.Error):
                pass
        return found

    for sig in (signal.SIGINT, signal.SIGKILL):
        left = members()
        for proc in left:
            try:
                proc.send_signal(sig)
            except psutil.Error:
                pass
        psutil.wait_procs(left, timeout=15)
