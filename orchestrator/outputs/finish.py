"""Finish a run directory its run could not finish (a full disk): write its bag from the
parts every node recorded, then its manifest. ``python -m orchestrator.outputs.finish RUN_DIR``
once there is space again; exit 0 when finished, 5 when a write fails again, 2 on bad input."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

EXIT_OK, EXIT_BAD_INPUT, EXIT_WRITE_FAILED = 0, 2, 5


def finish(run_dir: Path) -> Path:
    """Write ``run_dir``'s bag (the ticks its manifest says were recorded whole) and update
    its manifest; the bag's path. ValueError when the directory cannot be finished."""
    import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
    from descriptions.load import load_scenario
    from orchestrator.outputs.bag import write_bag
    from plan.run_paths import RunPaths
    from runtime.disk import write_atomically

    paths = RunPaths(run_dir)
    if not paths.manifest.is_file():
        raise ValueError(f"{run_dir} has no manifest.json: not a run directory cosim can "
                         "finish (run the scenario again)")
    manifest = json.loads(paths.manifest.read_text())
    if manifest.get("outputs", {}).get("bag"):
        raise ValueError(f"{run_dir} is finished already (it has its bag)")
    if not paths.parts.is_dir():
        raise ValueError(f"{run_dir} has neither a bag nor parts/ to write one from")
    entry = manifest["scenario"]
    scenario = load_scenario(Path(entry["file"]), dict(entry.get("overrides") or {}))
    failure = manifest.get("write_failure") or {}
    ticks = failure.get("complete_ticks", manifest.get("ticks") or 0)
    bag = write_bag(scenario, run_dir, int(ticks), finished=True)
    manifest["outputs"]["bag"] = "bag" if bag else None
    manifest["outputs"]["parts"] = None
    manifest["unfinished"] = None
    write_atomically(paths.manifest, json.dumps(manifest, indent=2) + "\n")
    shutil.rmtree(paths.parts, ignore_errors=True)
    return bag


def main(argv: list[str] | None = None) -> int:
    """Entry point: finish the run directory given."""
    from runtime.disk import WriteFailed

    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m orchestrator.outputs.finish RUN_DIR", file=sys.stderr)
        return EXIT_BAD_INPUT
    run_dir = Path(args[0])
    try:
        bag = finish(run_dir)
    except ValueError as exc:
        print(f"finish: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (WriteFailed, OSError) as exc:
        shutil.rmtree(run_dir / "bag", ignore_errors=True)
        print(f"finish: {exc}; parts/ are kept: free more space and run this again",
              file=sys.stderr)
        return EXIT_WRITE_FAILED
    print(f"finished {run_dir}: bag {bag}")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
