"""Where the time goes, by sampling: py-spy over a whole multi-process run, summarised per
process (orchestrator and each node) into what the lockstep costs are made of.

    python -m bench.profile [scenario.yaml] [--rate 250]

py-spy samples every process of the run from outside (``--subprocesses``, forked nodes
included) without changing their code; the nodes are told apart by the pids in the run's
manifest. Each sample is put in the category of its innermost frame that one of the rules
below recognises (``step``: the node's own code; ``serialise``: outputs to CDR; ...), so
the shares add up to the process's sampled busy time. Idle samples (blocked in a wait) are
left out by py-spy: the columns are busy time only.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from collections import Counter, defaultdict
from pathlib import Path

from bench.common import ORCHESTRATE, ROOT, RUN_TIMEOUT_S, bench_env

NAV = ROOT / "scenarios" / "nav.yaml"

# (category, substring of a frame "function (file:line)"); the innermost matching frame wins.
RULES = [
    ("serialise", "prepare_outputs ("), ("serialise", "cdr_encode.py"),
    ("deserialise", "InputHistory.take ("), ("deserialise", "deserialize_message ("),
    ("digest", "output_digest ("), ("digest", "RunDigest."),
    ("record", "nodes/recording.py"),
    ("report", "report_done ("), ("report", "encode_status ("),
    ("status decode", "decode_status ("),
    ("bookkeeping", "orchestrator/lockstep/acks.py"), ("bookkeeping", "LockstepMaster._decide ("),
    ("start-up", "LockstepMaster.wait_ready ("), ("start-up", "LockstepRuntime.wait_for_start ("),
    ("services", "orchestrator/ros_surface/simcontrol.py"),
    ("after the run", "orchestrator/outputs/bag.py"),
    ("after the run", "orchestrator/outputs/picture.py"),
    ("after the run", "orchestrator/outputs/report.py"),
    ("publish", ".publish ("), ("receive", ".wait ("), ("receive", "_take_all ("),
    ("step", "nodes/physics/"), ("step", "nodes/sensors/"), ("step", "nodes/control/"),
    ("step", "nodes/testing.py"),
    ("runtime", "runtime.py"), ("loop", "orchestrator/lockstep/master.py"),
    ("start-up", "<module>"), ("start-up", "_find_and_load"),
]
COLUMNS = ["step", "serialise", "deserialise", "publish", "receive", "report", "record",
           "digest", "status decode", "bookkeeping", "services", "runtime", "loop", "start-up",
           "after the run", "other"]


def record(scenario: Path, rate: int, out: Path) -> tuple[Path, dict] | str:
    """Run the scenario under py-spy; (raw samples file, manifest) or why it could not."""
    spy = shutil.which("py-spy", path=str(Path(sys.executable).parent)) or shutil.which("py-spy")
    if spy is None:
        return "py-spy is not installed (it comes with `pip install -e '.[dev]'`)"
    raw = out / "samples.txt"
    cmd = [spy, "record", "--subprocesses", "--nonblocking", "--rate", str(rate), "--format",
           "raw", "--output", str(raw), "--", *ORCHESTRATE,
           str(scenario), "--quiet", "--out", str(out / "runs")]
    proc = subprocess.run(cmd, env=bench_env(), capture_output=True, text=True, cwd=ROOT,
                          timeout=RUN_TIMEOUT_S)
    manifests = list((out / "runs").glob("*/manifest.json"))
    if not raw.exists() or not manifests:
        return f"py-spy could not sample the run: {proc.stderr.strip()[-300:]}"
    return raw, json.loads(manifests[0].read_text())


def categorise(frames: list[str]) -> str:
    """The category of one sample: the innermost frame a rule recognises."""
    for frame in reversed(frames):
        for category, needle in RULES:
            if needle in frame:
                return category
    return "other"


def summarise(raw: Path, manifest: dict) -> dict[str, tuple[Counter, Counter]]:
    """Per process name: (samples per category, samples per innermost function)."""
    names = {str(n["pid"]): name for name, n in manifest["nodes"].items() if n.get("pid")}
    out: dict[str, tuple[Counter, Counter]] = defaultdict(lambda: (Counter(), Counter()))
    for line in raw.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        frames = stack.split(";")
        procs = [f for f in frames if f.startswith("process ")]
        if not procs or not count.isdigit():
            continue
        pid = procs[-1].split(":")[0].split()[1]
        code = [f for f in frames if not f.startswith("process ")]
        if not code:
            continue
        cats, leaves = out[names.get(pid, "orchestrator")]  # the one process not a node
        cats[categorise(code)] += int(count)
        leaves[code[-1]] += int(count)
    return dict(out)


def print_summary(summary: dict[str, tuple[Counter, Counter]], rate: int) -> None:
    """One row per process: busy seconds and the share of each category; then top functions."""
    used = [c for c in COLUMNS if any(cats[c] for cats, _ in summary.values())]
    print(f"{'process':14s} {'busy s':>7s}  " + " ".join(f"{c[:11]:>11s}" for c in used))
    for name, (cats, _) in sorted(summary.items()):
        total = sum(cats.values())
        print(f"{name:14s} {total / rate:7.2f}  " +
              " ".join(f"{100 * cats[c] / total:10.0f}%" for c in used))
    for name, (_, leaves) in sorted(summary.items()):
        total = sum(leaves.values())
        top = ", ".join(f"{f.split(' (')[0]} {100 * n / total:.0f}%"
                        for f, n in leaves.most_common(5))
        print(f"  {name}: {top}")


def main(argv: list[str] | None = None) -> None:
    """Profile one run (nav.yaml by default) and print where each process spent its time."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", nargs="?", type=Path, default=NAV)
    p.add_argument("--rate", type=int, default=250, help="samples per second per process")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="cosim-profile-") as tmp:
        got = record(args.scenario, args.rate, Path(tmp))
        if isinstance(got, str):
            print(f"not measured: {got}")
            return
        raw, manifest = got
        print(f"{args.scenario.name}: digest {manifest['digest'][:12]}, loop "
              f"{manifest['loop_s']:.2f} s, sampled at {args.rate}/s per process (busy only)")
        print_summary(summarise(raw, manifest), args.rate)


if __name__ == "__main__":
    main()
