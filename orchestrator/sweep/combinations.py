"""The runs of a sweep: every combination of seeds and parameter values, each one run.

``--seeds 1-100`` (or ``1,5,9`` or ``1-3,10``) and ``--set KEY=V1,V2,...`` (the values a
YAML flow sequence, so ``--set goal.x=1.0,2.5`` or ``--set nodes.a.params.list=[1,2],[3,4]``)
give the product of seeds and values. Each run has an id made of its seed and values, so
the same run keeps its directory and record when a sweep is resumed or extended.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: its scenario, seed and parameter values, and where it writes."""

    run_id: str
    scenario: Path  # absolute
    seed: int
    params: dict[str, Any] = field(hash=False)  # dotted key -> value, in the sweep's order
    out: Path  # absolute: the run's own directory; the run directory is made inside it
    in_process: bool = True
    processes: int = 1  # OS processes the run needs: 1 in-process, nodes + orchestrator
    picture: bool = True  # the run's report.png (--no-picture: a CPU second a run saved)

    def overrides(self) -> dict[str, Any]:
        """The run's scenario overrides (its seed and values), as ``--set`` gives them."""
        return {"seed": self.seed, **self.params}

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, for the record and for a Ray task's arguments."""
        return {"run_id": self.run_id, "scenario": str(self.scenario), "seed": self.seed,
                "params": self.params, "out": str(self.out), "in_process": self.in_process,
                "processes": self.processes, "picture": self.picture}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunSpec:
        """The inverse of ``as_dict``."""
        return cls(data["run_id"], Path(data["scenario"]), data["seed"], dict(data["params"]),
                   Path(data["out"]), data["in_process"], data["processes"],
                   data.get("picture", True))


def parse_seeds(text: str) -> list[int]:
    """'1-100' -> [1..100]; '1,5,9'; '1-3,10' (order kept, duplicates dropped)."""
    seeds: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        match = re.fullmatch(r"(-?\d+)(?:\s*-\s*(-?\d+))?", part)
        if not match:
            raise ValueError(f"--seeds {text!r}: {part!r} is not a seed or a range FIRST-LAST "
                             "(accepted: 1-100, 1,5,9, 1-3,10)")
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        if last < first:
            raise ValueError(f"--seeds {text!r}: the range {part} is empty (write FIRST-LAST "
                             "with FIRST <= LAST)")
        seeds.extend(s for s in range(first, last + 1) if s not in seeds)
    if not seeds:
        raise ValueError("--seeds: no seed given (e.g. --seeds 1-100)")
    return seeds


def parse_sweep_sets(pairs: list[str]) -> dict[str, list[Any]]:
    """['a.b=1,2', 'c=x'] -> {'a.b': [1, 2], 'c': ['x']}: the values of each key, YAML."""
    out: dict[str, list[Any]] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--set {pair!r}: expected KEY=V1,V2,... "
                             "(e.g. nodes.control.params.max_speed=0.3,0.5)")
        if key == "seed":
            raise ValueError(f"--set {pair!r}: give seeds with --seeds, e.g. --seeds 1-100")
        try:
            values = yaml.safe_load(f"[{text}]")
        except yaml.YAMLError as exc:
            raise ValueError(f"--set {pair!r}: the values are not a YAML list ({exc}); "
                             "separate values with commas, e.g. 0.3,0.5 or [1,2],[3,4]"
                             ) from None
        if not values:
            raise ValueError(f"--set {pair!r}: no value given")
        if key in out:
            raise ValueError(f"--set {key} is given twice; list all its values once: "
                             f"--set {key}=V1,V2,...")
        out[key] = values
    return out


def run_id(seed: int, params: dict[str, Any]) -> str:
    """'seed3_max_speed0.4_1a2b3c': readable (seed, each key's last part and its value)
    and unique (a hash of the exact keys and values)."""
    exact = json.dumps({"seed": seed, **params}, sort_keys=True, default=str)
    digest = hashlib.sha256(exact.encode()).hexdigest()[:6]
    parts = [f"seed{seed}"] + [f"{key.rsplit('.', 1)[-1]}{_slug(value)}"
                               for key, value in params.items()]
    readable = re.sub(r"[^A-Za-z0-9._=+-]+", "-", "_".join(parts))[:80]
    return f"{readable}_{digest}"


def _slug(value: Any) -> str:
    """A value as short path-safe text."""
    return yaml.safe_dump(value, default_flow_style=True, width=1000).strip().removesuffix(
        "...").strip()


def combinations(values: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """Every combination of the swept values ([{}] when nothing is swept)."""
    keys = list(values)
    return [dict(zip(keys, combo, strict=True))
            for combo in itertools.product(*(values[k] for k in keys))]


def plan_runs(scenario: Path, seeds: list[int], values: dict[str, list[Any]], out: Path,
              in_process: bool, processes: int, picture: bool = True) -> list[RunSpec]:
    """The runs of a sweep, seed-major: every value combination for seed 1, then seed 2..."""
    scenario, runs_dir = scenario.resolve(), (out / "runs").resolve()
    runs = []
    for seed in seeds:
        for params in combinations(values):
            rid = run_id(seed, params)
            runs.append(RunSpec(rid, scenario, seed, params, runs_dir / rid, in_process,
                                processes, picture))
    return runs
