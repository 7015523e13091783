"""pytest plugin for cosim (registered through the ``pytest11`` entry point): installing cosim
is enough.

- ``cosim`` fixture: ``cosim.run(scenario, in_process=..., **overrides)`` runs a scenario in a
  ROS domain of the test's own (ROS_DOMAIN_ID, reserved so that no other test or session on
  this machine uses it at the same time) and returns an ``orchestrator.api.FinishedRun``. When the
  test ends, pass or fail, every process the test started is stopped: those that carry its
  token (programs started after it was set) and its new descendants, orphans included (a
  forked process shows no token, and while the test runs its process adopts the orphans
  among its descendants, on Linux).
- ``@pytest.mark.cosim_seeds(1, 2, 3)``: the test runs once per seed; ``cosim.run`` uses it.
- Golden digests: ``pytest --cosim-update-golden`` records every run's digest (and a compact
  per-topic, per-tick hash list, the rendered topics, the digest without them, and the
  versions a digest depends on) in ``<test file stem>.golden.json`` beside the test, keyed by
  test name; later runs fail when the digest changes, naming the first topic and tick that
  differ and the versions that differ from the golden run's.
- ``pytest --cosim-ignore-rendered`` (or ``cosim.run(..., ignore_rendered=True)``): golden
  checks compare the digest without the rendered topics (camera images, whose pixels depend
  on the GL renderer), and say which topics were left out.

Nothing heavy is imported until a test uses the fixture.
"""

from __future__ import annotations

import json
import os
import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from orchestrator.domains import DOMAINS, DomainLease, domains_in_use  # noqa: F401 - also here

if TYPE_CHECKING:
    from plan.scenario import Scenario

TOKEN_ENV = "COSIM_PYTEST_TOKEN"
"""Set in every process a test starts, so the clean-up finds them wherever they went."""
GOLDEN_SUFFIX = ".golden.json"
RUNS_KEY = pytest.StashKey[list]()
GOLDEN_KEY = pytest.StashKey["GoldenStore"]()


def pytest_addoption(parser: pytest.Parser) -> None:
    """--cosim-update-golden and --cosim-out."""
    group = parser.getgroup("cosim", "cosim co-simulation runs")
    group.addoption("--cosim-update-golden", action="store_true", default=False,
                    help="record the digest of every cosim run into <test file>.golden.json "
                         "instead of checking it")
    group.addoption("--cosim-ignore-rendered", action="store_true", default=False,
                    help="golden checks compare the digest without the rendered topics "
                         "(camera images: their pixels depend on the GL renderer)")
    group.addoption("--cosim-out", default=None, metavar="DIR",
                    help="write cosim run directories under DIR (default: pytest's tmp dir)")


def pytest_configure(config: pytest.Config) -> None:
    """Declare the marker and set up the golden store."""
    config.addinivalue_line("markers", "cosim_seeds(*seeds): run the test once per seed; "
                            "the cosim fixture's runs use that seed")
    config.stash[GOLDEN_KEY] = GoldenStore(config.getoption("cosim_update_golden"),
                                           config.getoption("cosim_ignore_rendered"))


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrise tests marked cosim_seeds over their seeds (through the cosim_seed fixture)."""
    marker = metafunc.definition.get_closest_marker("cosim_seeds")
    if marker is None:
        return
    seeds = list(marker.args[0]) if len(marker.args) == 1 and not isinstance(
        marker.args[0], int) else list(marker.args)
    if "cosim_seed" not in metafunc.fixturenames:
        pytest.fail(f"{metafunc.definition.nodeid}: @pytest.mark.cosim_seeds needs the cosim "
                    "(or cosim_seed) fixture", pytrace=False)
    metafunc.parametrize("cosim_seed", seeds, ids=[f"seed={s}" for s in seeds], indirect=True)


@pytest.fixture
def cosim_seed(request: pytest.FixtureRequest) -> int | None:
    """The seed of this test from @pytest.mark.cosim_seeds, None without the marker."""
    return getattr(request, "param", None)


@pytest.fixture
def cosim(request: pytest.FixtureRequest, cosim_seed: int | None,
          tmp_path_factory: pytest.TempPathFactory):
    """Runs scenarios for this test in a ROS domain of its own; stops every process after."""
    out = request.config.getoption("cosim_out")
    out = Path(out) if out else tmp_path_factory.mktemp("cosim", numbered=True)
    session = Cosim(request, cosim_seed, out)
    request.node.stash[RUNS_KEY] = session.runs
    adopting = set_subreaper(True)
    with DomainLease() as domain, _environment({"ROS_DOMAIN_ID": str(domain),
                                                TOKEN_ENV: session.token}):
        session.domain_id = domain
        try:
            yield session
        finally:
            stop_processes(session.token, session.children_before)
            if adopting is False:
                set_subreaper(False)


class Cosim:
    """What a test gets from the ``cosim`` fixture."""

    def __init__(self, request: pytest.FixtureRequest, seed: int | None, out: Path):
        self.request = request
        self.seed = seed
        self.out = out
        self.domain_id: int | None = None
        self.runs: list = []
        self.token = uuid.uuid4().hex
        self.children_before = _child_pids()

    def load(self, scenario: str | Path | Scenario, **overrides: Any) -> Scenario:
        """Load a scenario with overrides (and this test's seed); see orchestrator.api.load."""
        from orchestrator.api import load

        return load(scenario, **self._with_seed(overrides))

    def run(self, scenario: str | Path | Scenario, *, in_process: bool = False,
            check: bool = True, golden: bool = True, ignore_rendered: bool | None = None,
            **overrides: Any):
        """Run a scenario (see orchestrator.api.run) with this test's seed, in this test's ROS
        domain; check (or with --cosim-update-golden, record) its golden digest, without the
        rendered topics when ``ignore_rendered`` (default: --cosim-ignore-rendered)."""
        from orchestrator.api import run

        result = run(scenario, in_process=in_process, out=self.out, check=check,
                     **self._with_seed(overrides))
        self.runs.append(result)
        if golden and result.digest:
            store: GoldenStore = self.request.config.stash[GOLDEN_KEY]
            key = self._golden_key(len(self.runs))
            problem = store.check(_golden_file(self.request), key, result, ignore_rendered)
            if problem:
                pytest.fail(problem, pytrace=False)
        return result

    def _with_seed(self, overrides: dict[str, Any]) -> dict[str, Any]:
        """Overrides with this test's seed unless one is given."""
        if self.seed is not None and overrides.get("seed") is None:
            return {**overrides, "seed": self.seed}
        return overrides

    def _golden_key(self, n: int) -> str:
        """The test's name within its file ('test_x[seed=1]'), '#n' for its n-th run (n > 1)."""
        name = self.request.node.nodeid.split("::", 1)[-1]
        return name if n == 1 else f"{name}#{n}"


def _golden_file(request: pytest.FixtureRequest) -> Path:
    """<dir>/<test file stem>.golden.json beside the test file."""
    path = Path(request.node.path)
    return path.with_name(path.stem + GOLDEN_SUFFIX)


class GoldenStore:
    """Golden digests: read lazily per test file, checked per run, written at session end."""

    def __init__(self, update: bool, ignore_rendered: bool = False):
        self.update = update
        self.ignore_rendered = ignore_rendered
        self.files: dict[Path, dict[str, Any]] = {}
        self.changed: set[Path] = set()
        self.unrecorded = 0

    def entries(self, file: Path) -> dict[str, Any]:
        """The golden entries of a file (empty when it does not exist)."""
        if file not in self.files:
            self.files[file] = json.loads(file.read_text()).get("runs", {}) \
                if file.exists() else {}
        return self.files[file]

    def check(self, file: Path, key: str, result, ignore_rendered: bool | None = None
              ) -> str | None:
        """Record (when updating) or compare a run with its golden entry (without its rendered
        topics when ``ignore_rendered``, default the store's); a message when the digest
        changed, else None."""
        from orchestrator.outputs.diff import (
            DIGEST_KEYS,
            fingerprint,
            read_manifest,
            run_dir_entries,
        )
        from plan.timeutil import tick_text

        entries = self.entries(file)
        manifest = read_manifest(result.run_dir)
        if self.update:
            found = run_dir_entries(result.run_dir)[0] if result.bag else []
            entries[key] = {"digest": result.digest, "scenario": result.scenario.name,
                            "seed": result.scenario.model.seed,
                            "tick_ns": tick_text(result.scenario.tick_ns),
                            "messages": fingerprint(found),
                            "digest_without_rendered": manifest.get("digest_without_rendered"),
                            "rendered_topics": manifest.get("rendered_topics", []),
                            "versions": manifest.get("digest_versions", {})}
            self.changed.add(file)
            return None
        golden = entries.get(key)
        if golden is None:
            self.unrecorded += 1
            return None
        ignore = self.ignore_rendered if ignore_rendered is None else ignore_rendered
        field = DIGEST_KEYS[ignore]
        if ignore and not golden.get(field):
            return (f"cosim: the golden entry {key} in {file.name} has no {field} (recorded "
                    "before cosim kept per-topic digests); record it again with "
                    "pytest --cosim-update-golden")
        if golden[field] == manifest.get(field):
            return None
        return mismatch_message(file, key, golden, result, ignore)

    def write(self) -> list[Path]:
        """Write every golden file that changed; return them."""
        for file in sorted(self.changed):
            doc = {"about": "cosim golden digests; record with pytest --cosim-update-golden",
                   "runs": dict(sorted(self.files[file].items()))}
            file.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
        return sorted(self.changed)


def mismatch_message(file: Path, key: str, golden: dict[str, Any], result,
                     ignore_rendered: bool = False) -> str:
    """The failure text of a changed digest: the first topic and tick that differ, the
    rendered topics left out (``ignore_rendered``), the versions that differ."""
    from orchestrator.outputs.diff import (
        DIGEST_KEYS,
        fingerprint_entries,
        first_difference,
        left_out_text,
        read_manifest,
        run_dir_entries,
        versions_text,
    )

    manifest = read_manifest(result.run_dir)
    rendered = sorted(set(manifest.get("rendered_topics") or [])
                      | set(golden.get("rendered_topics") or []))
    actual, tick_ns = run_dir_entries(result.run_dir) if result.bag else ([], None)
    reference = fingerprint_entries(golden.get("messages", {}))
    if ignore_rendered:
        actual = [e for e in actual if e[1] not in rendered]
        reference = [e for e in reference if e[1] not in rendered]
    diff = first_difference(reference, actual, tick_ns)
    where = diff.describe() if diff else ("every recorded message matches the golden hashes; "
                                          "what else the digest covers changed (nodes, schedule)")
    field = DIGEST_KEYS[ignore_rendered]
    what = f"digest {left_out_text(rendered)}" if ignore_rendered else "run digest"
    lines = [f"cosim: the {what} of {key} changed.",
             f"  golden: {golden.get(field)}  ({file.name}, seed {golden.get('seed')})",
             f"  now:    {manifest.get(field)}  (seed {result.scenario.model.seed})",
             f"  first difference: {where}"]
    versions = versions_text(golden.get("versions"), manifest.get("digest_versions"))
    if versions:
        lines.append(f"  versions:{versions}")
    if not ignore_rendered and rendered and golden.get("digest_without_rendered") and \
            golden["digest_without_rendered"] == manifest.get("digest_without_rendered"):
        lines.append(f"  only the rendered topics ({', '.join(rendered)}) differ: their pixels "
                     "depend on the renderer; pytest --cosim-ignore-rendered (or "
                     "cosim.run(..., ignore_rendered=True)) compares without them")
    lines += [f"  this run: {result.run_dir}",
              "If the change is intended, record the new digests with: "
              "pytest --cosim-update-golden"]
    return "\n".join(lines)


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Write the golden files recorded with --cosim-update-golden."""
    store = session.config.stash.get(GOLDEN_KEY, None)
    if store is not None:
        store.write()


def pytest_terminal_summary(terminalreporter, config: pytest.Config) -> None:
    """Say which golden files were written, and how many runs had no golden digest."""
    store = config.stash.get(GOLDEN_KEY, None)
    if store is None:
        return
    for file in sorted(store.changed):
        terminalreporter.write_line(f"cosim: recorded golden digests in {file}")
    if store.unrecorded and not store.update:
        terminalreporter.write_line(f"cosim: {store.unrecorded} run(s) have no golden digest "
                                    "(record them with --cosim-update-golden)")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call):
    """Add the test's cosim runs (status, digest, run directory) to a failure's report."""
    outcome = yield
    report = outcome.get_result()
    runs = item.stash.get(RUNS_KEY, None)
    if report.failed and runs:
        text = "\n".join(r.summary() for r in runs)
        report.sections.append(("cosim runs", text))


class _environment:
    """Set environment variables for a block; restore them after."""

    def __init__(self, values: dict[str, str]):
        self.values = values
        self.saved: dict[str, str | None] = {}

    def __enter__(self) -> None:
        for key, value in self.values.items():
            self.saved[key] = os.environ.get(key)
            os.environ[key] = value

    def __exit__(self, *exc: object) -> None:
        for key, value in self.saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


PR_SET_CHILD_SUBREAPER = 36
PR_GET_CHILD_SUBREAPER = 37


def set_subreaper(on: bool) -> bool | None:
    """Make this process adopt (``on``) or stop adopting the orphans among its descendants,
    so that a forked process whose parent died is still found as a descendant. Returns the
    previous setting; None where the system has no such thing (not Linux)."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        flag = ctypes.c_int(0)
        if libc.prctl(PR_GET_CHILD_SUBREAPER, ctypes.byref(flag), 0, 0, 0) != 0:
            return None
        libc.prctl(PR_SET_CHILD_SUBREAPER, int(on), 0, 0, 0)
        return bool(flag.value)
    except (OSError, AttributeError):
        return None


def _child_pids() -> set[int]:
    """The pids of this process's descendants now."""
    import psutil

    return {p.pid for p in psutil.Process().children(recursive=True)}


def stop_processes(token: str, before: set[int]) -> list[int]:
    """Stop every process a test started: new descendants (adopted orphans included) and any
    process carrying its token (SIGINT, then SIGTERM, then SIGKILL). Returns the pids that
    had to be stopped."""
    import psutil

    from orchestrator.lockstep.supervisor import escalate

    me = psutil.Process()
    procs = {p.pid: p for p in me.children(recursive=True) if p.pid not in before}
    for proc in psutil.process_iter():
        try:
            if proc.pid != me.pid and proc.environ().get(TOKEN_ENV) == token:
                procs[proc.pid] = proc
        except (psutil.Error, OSError):
            continue
    escalate(list(procs.values()))
    return sorted(procs)
